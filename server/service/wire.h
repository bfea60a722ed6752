// Conversions between the API's messages and the core's types, and the one mapping from
// absl::Status to grpc::Status.
#ifndef ACTOPO_SERVER_SERVICE_WIRE_H_
#define ACTOPO_SERVER_SERVICE_WIRE_H_

#include <grpcpp/support/status.h>

#include <optional>
#include <span>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "actopo/v1/topology_service.pb.h"
#include "server/algorithms/registry.h"
#include "server/core/relation.h"
#include "server/io/vtk_writer.h"
#include "server/service/mesh_registry.h"
#include "server/service/session.h"

namespace actopo::service {

namespace pb = ::actopo::v1;

// absl and gRPC share their code numbers; the message (which names the field and value) is
// kept as is.
grpc::Status ToGrpcStatus(const absl::Status& status);

absl::StatusOr<Relation> FromProto(pb::Relation r);
pb::Relation ToProto(Relation r);
absl::StatusOr<Algorithm> FromProto(pb::Algorithm a);
absl::StatusOr<SessionOptions> FromProto(const pb::OpenSessionRequest& request);
PartitionOptions FromProto(const pb::PartitionOptions& p);

void Fill(const LoadedMesh& mesh, int sessions, pb::MeshInfo* out);
// `running_job`: SessionManager::RunningJob of the session.
void Fill(Session& session, const std::string& running_job, pb::SessionInfo* out);
void Fill(const EngineStats& stats, pb::EngineStats* out);
void Fill(const MemoryStats& memory, pb::MemoryStats* out);

// Raw little-endian arrays.
void Pack(const std::string& name, std::span<const int64_t> values, pb::Array* out);
void Pack(const std::string& name, const io::NamedArray& values, pb::Array* out);
void PackPoints(const std::string& name, std::span<const double> xyz, pb::Array* out);
size_t DataTypeSize(pb::DataType t);
// Reads an integer array (INT32 or INT64) of any shape; `field` names it in errors.
absl::StatusOr<std::vector<int64_t>> UnpackIntegers(const pb::Array& array,
                                                    std::string_view field);

}  // namespace actopo::service

#endif  // ACTOPO_SERVER_SERVICE_WIRE_H_
