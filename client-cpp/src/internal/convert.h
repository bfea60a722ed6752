// The API's messages turned into the public structs, and arrays into messages.
#ifndef ACTOPO_CLIENT_SRC_INTERNAL_CONVERT_H_
#define ACTOPO_CLIENT_SRC_INTERNAL_CONVERT_H_

#include <span>
#include <string>

#include "actopo/client.h"
#include "actopo/v1/topology_service.pb.h"

namespace actopo::client::internal {

ServerInfo FromProto(const v1::GetServerInfoResponse& info);
MeshInfo FromProto(const v1::MeshInfo& mesh);
UploadStatus FromProto(const v1::UploadStatus& upload);
SessionInfo FromProto(const v1::SessionInfo& session);
SessionStats FromProto(const v1::GetSessionStatsResponse& stats);
JobStats FromProto(const v1::JobStats& stats);
EngineStats FromProto(const v1::EngineStats& engine);
MemoryStats FromProto(const v1::MemoryStats& memory);

v1::PartitionOptions ToProto(const PartitionOptions& partition);

// An int64 array of shape `shape` (little-endian, as the wire wants).
void PackInt64(std::span<const int64_t> values, std::span<const int64_t> shape, v1::Array* out);
// The values of an int64 array (`field` names it in errors); checks dtype and size.
absl::StatusOr<std::vector<int64_t>> UnpackInt64(const v1::Array& array, std::string_view field);

}  // namespace actopo::client::internal

#endif  // ACTOPO_CLIENT_SRC_INTERNAL_CONVERT_H_
