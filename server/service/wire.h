// Conversions between the API's messages and the core's types, and the one mapping from
// absl::Status to grpc::Status.
#ifndef ACTOPO_SERVER_SERVICE_WIRE_H_
#define ACTOPO_SERVER_SERVICE_WIRE_H_

#include <grpcpp/support/status.h>

#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "absl/status/statusor.h"
#include "actopo/v1/topology_service.pb.h"
#include "google/protobuf/struct.pb.h"
#include "server/algorithms/registry.h"
#include "server/core/relation.h"
#include "server/io/vtk_writer.h"
#include "server/results/run_algorithm.h"
#include "server/service/mesh_registry.h"
#include "server/service/session.h"

namespace actopo::service {

namespace pb = ::actopo::v1;

// absl and gRPC share their code numbers; the message (which names the field and value) is
// kept as is.
grpc::Status ToGrpcStatus(const absl::Status& status);

// One row of a mapping between an API enum and a core enum.
template <class Proto, class Core>
struct EnumMapping {
  Proto proto;
  Core core;
};

// The API <-> core enum mappings: one row per API value, none for _UNSPECIFIED (whose meaning,
// if any, is the caller's: the default structure, the algorithm's prefetch and precompute).
// wire_test checks that every API value has exactly one row, that every row round-trips and
// that the names agree, so a value added to the proto without a row fails it.
inline constexpr EnumMapping<pb::Relation, Relation> kRelationMapping[] = {
    {pb::RELATION_VERTEX_NEIGHBORS, Relation::kVV},
    {pb::RELATION_VERTEX_EDGES, Relation::kVE},
    {pb::RELATION_VERTEX_TRIANGLES, Relation::kVF},
    {pb::RELATION_VERTEX_STAR, Relation::kVT},
    {pb::RELATION_EDGE_VERTICES, Relation::kEV},
    {pb::RELATION_EDGE_TRIANGLES, Relation::kEF},
    {pb::RELATION_EDGE_STAR, Relation::kET},
    {pb::RELATION_TRIANGLE_VERTICES, Relation::kFV},
    {pb::RELATION_TRIANGLE_EDGES, Relation::kFE},
    {pb::RELATION_TRIANGLE_STAR, Relation::kFT},
    {pb::RELATION_TETRAHEDRON_VERTICES, Relation::kTV},
    {pb::RELATION_TETRAHEDRON_EDGES, Relation::kTE},
    {pb::RELATION_TETRAHEDRON_TRIANGLES, Relation::kTF},
    {pb::RELATION_TETRAHEDRON_NEIGHBORS, Relation::kTT},
    {pb::RELATION_VERTEX_LINK, Relation::kVL},
    {pb::RELATION_EDGE_LINK, Relation::kEL},
    {pb::RELATION_TRIANGLE_LINK, Relation::kFL},
    {pb::RELATION_VERTEX_ON_BOUNDARY, Relation::kVB},
    {pb::RELATION_EDGE_ON_BOUNDARY, Relation::kEB},
    {pb::RELATION_TRIANGLE_ON_BOUNDARY, Relation::kFB},
    {pb::RELATION_EDGE_NEIGHBORS, Relation::kEE},
    {pb::RELATION_TRIANGLE_NEIGHBORS, Relation::kFF},
};
inline constexpr EnumMapping<pb::Algorithm, Algorithm> kAlgorithmMapping[] = {
    {pb::ALGORITHM_TOPO_RELATIONS, Algorithm::kTopoRelations},
    {pb::ALGORITHM_CRITICAL_POINTS, Algorithm::kCriticalPoints},
    {pb::ALGORITHM_DISCRETE_GRADIENT, Algorithm::kDiscreteGradient},
    {pb::ALGORITHM_MORSE_SMALE, Algorithm::kMorseSmale},
    {pb::ALGORITHM_PERSISTENCE_DIAGRAM, Algorithm::kPersistenceDiagram},
    {pb::ALGORITHM_TOPOLOGICAL_SIMPLIFICATION, Algorithm::kTopologicalSimplification},
    {pb::ALGORITHM_DIAGRAM_DISTANCE, Algorithm::kDiagramDistance},
    {pb::ALGORITHM_TRACKING, Algorithm::kTracking},
    {pb::ALGORITHM_MERGE_TREE, Algorithm::kMergeTree},
    {pb::ALGORITHM_CONTOUR_TREE, Algorithm::kContourTree},
};
inline constexpr EnumMapping<pb::Structure, StructureKind> kStructureMapping[] = {
    {pb::STRUCTURE_EXPLICIT, StructureKind::kExplicit},
    {pb::STRUCTURE_COMPACT, StructureKind::kCompact},
    {pb::STRUCTURE_ACTOPO, StructureKind::kActopo},
};
inline constexpr EnumMapping<pb::Prefetch, Prefetch> kPrefetchMapping[] = {
    {pb::PREFETCH_LINEAR, Prefetch::kLinear},
    {pb::PREFETCH_SPATIAL, Prefetch::kSpatial},
    {pb::PREFETCH_ADAPTIVE, Prefetch::kAdaptive},
};
inline constexpr EnumMapping<pb::Precompute, Precompute> kPrecomputeMapping[] = {
    {pb::PRECOMPUTE_REQUESTED, Precompute::kRequested},
    {pb::PRECOMPUTE_DECLARED, Precompute::kDeclared},
};

// A value without a row (_UNSPECIFIED included) is INVALID_ARGUMENT naming the field and value.
absl::StatusOr<Relation> FromProto(pb::Relation r);
absl::StatusOr<Algorithm> FromProto(pb::Algorithm a);
absl::StatusOr<StructureKind> FromProto(pb::Structure s);
absl::StatusOr<Prefetch> FromProto(pb::Prefetch p);
absl::StatusOr<Precompute> FromProto(pb::Precompute p);
pb::Relation ToProto(Relation r);
pb::Algorithm ToProto(Algorithm a);
pb::Structure ToProto(StructureKind s);
pb::Prefetch ToProto(Prefetch p);
pb::Precompute ToProto(Precompute p);

absl::StatusOr<SessionOptions> FromProto(const pb::OpenSessionRequest& request);
PartitionOptions FromProto(const pb::PartitionOptions& p);

void Fill(const LoadedMesh& mesh, int sessions, pb::MeshInfo* out);
// `running_job`: SessionManager::RunningJob of the session.
void Fill(Session& session, const std::string& running_job, pb::SessionInfo* out);
void Fill(const EngineStats& stats, pb::EngineStats* out);
void Fill(const MemoryStats& memory, pb::MemoryStats* out);

// A job's summary: actopo-bench's "result" (Summarize in run_algorithm.h, the one place that
// spells its keys) copied node by node into a Struct. Numbers are doubles, as in any Struct.
void FillSummary(const AlgorithmResult& result, const Topology& topology,
                 const SummaryOptions& options, google::protobuf::Struct* out);
// Any JSON object (diagram-distance's matrices, a many-field job's summary) the same way.
void FillStruct(const nlohmann::ordered_json& json, google::protobuf::Struct* out);

// Raw little-endian arrays. Describe* fill `out`'s name, type and shape and return the array's
// bytes where they lie, for a caller that sends them in pieces (a job's result: no second copy
// of a large array); Pack also copies the bytes into `out` (a relation answer's CSR arrays).
std::string_view Describe(const std::string& name, std::span<const int64_t> values, pb::Array* out);
std::string_view Describe(const std::string& name, const io::NamedArray& values, pb::Array* out);
std::string_view DescribePoints(const std::string& name, std::span<const double> xyz,
                                pb::Array* out);
void Pack(const std::string& name, std::span<const int64_t> values, pb::Array* out);
size_t DataTypeSize(pb::DataType t);
// Reads an integer array (INT32 or INT64) of any shape; `field` names it in errors.
absl::StatusOr<std::vector<int64_t>> UnpackIntegers(const pb::Array& array, std::string_view field);

}  // namespace actopo::service

#endif  // ACTOPO_SERVER_SERVICE_WIRE_H_
