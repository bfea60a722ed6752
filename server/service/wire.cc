#include "server/service/wire.h"

#include <bit>
#include <cstring>

#include "absl/algorithm/container.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "google/protobuf/util/time_util.h"
#include "server/core/parallel.h"

namespace actopo::service {

static_assert(std::endian::native == std::endian::little,
              "arrays travel as raw little-endian bytes");

grpc::Status ToGrpcStatus(const absl::Status& status) {
  if (status.ok()) return grpc::Status::OK;
  return grpc::Status(static_cast<grpc::StatusCode>(status.code()), std::string(status.message()));
}

absl::StatusOr<Relation> FromProto(pb::Relation r) {
  const int i = int(r) - 1;
  if (i < 0 || i >= kNumRelations) {
    return absl::InvalidArgumentError(
        absl::StrCat("relation: ", pb::Relation_Name(r).empty() ? std::to_string(int(r))
                                                                 : pb::Relation_Name(r),
                     " is not a relation; set one of RELATION_VERTEX_NEIGHBORS ... "
                     "RELATION_TRIANGLE_NEIGHBORS"));
  }
  return static_cast<Relation>(i);
}

pb::Relation ToProto(Relation r) { return static_cast<pb::Relation>(Index(r) + 1); }

absl::StatusOr<Algorithm> FromProto(pb::Algorithm a) {
  const int i = int(a) - 1;
  if (i < 0 || i >= int(AllAlgorithms().size())) {
    return absl::InvalidArgumentError(absl::StrCat(
        "algorithm: ", pb::Algorithm_Name(a).empty() ? std::to_string(int(a)) : pb::Algorithm_Name(a),
        " is not an algorithm; set ALGORITHM_TOPO_RELATIONS, ALGORITHM_CRITICAL_POINTS, "
        "ALGORITHM_DISCRETE_GRADIENT or ALGORITHM_MORSE_SMALE"));
  }
  return AllAlgorithms()[i];
}

absl::StatusOr<SessionOptions> FromProto(const pb::OpenSessionRequest& r) {
  SessionOptions o;
  o.scalar_field = r.scalar_field();
  switch (r.structure()) {
    case pb::STRUCTURE_UNSPECIFIED:
    case pb::STRUCTURE_ACTOPO: o.structure = StructureKind::kActopo; break;
    case pb::STRUCTURE_EXPLICIT: o.structure = StructureKind::kExplicit; break;
    case pb::STRUCTURE_COMPACT: o.structure = StructureKind::kCompact; break;
    default:
      return absl::InvalidArgumentError(
          absl::StrCat("structure: ", int(r.structure()), " is not a structure"));
  }
  const pb::EngineOptions& e = r.engine();
  const ThreadPlan plan = DefaultThreadPlan(o.structure == StructureKind::kActopo);
  o.consumers = e.consumers() != 0 ? e.consumers() : plan.consumers;
  o.producers = e.producers() != 0 ? e.producers() : std::max(plan.producers, 1);
  if (e.buffer_ratio() != 0) o.buffer_ratio = e.buffer_ratio();
  o.query_readers = e.query_readers() != 0 ? e.query_readers() : std::min(DefaultThreads(), 4);
  switch (e.prefetch()) {
    case pb::PREFETCH_UNSPECIFIED: break;
    case pb::PREFETCH_LINEAR: o.prefetch = Prefetch::kLinear; break;
    case pb::PREFETCH_SPATIAL: o.prefetch = Prefetch::kSpatial; break;
    case pb::PREFETCH_ADAPTIVE: o.prefetch = Prefetch::kAdaptive; break;
    default:
      return absl::InvalidArgumentError(
          absl::StrCat("engine.prefetch: ", int(e.prefetch()), " is not a prefetch mode"));
  }
  switch (e.precompute()) {
    case pb::PRECOMPUTE_UNSPECIFIED: break;
    case pb::PRECOMPUTE_REQUESTED: o.precompute = Precompute::kRequested; break;
    case pb::PRECOMPUTE_DECLARED: o.precompute = Precompute::kDeclared; break;
    default:
      return absl::InvalidArgumentError(
          absl::StrCat("engine.precompute: ", int(e.precompute()), " is not a scope"));
  }
  return o;
}

PartitionOptions FromProto(const pb::PartitionOptions& p) {
  return {.bucket_capacity = p.block_size(), .block_label_field = p.block_label_field()};
}

namespace {

google::protobuf::Timestamp Stamp(absl::Time t) {
  return google::protobuf::util::TimeUtil::NanosecondsToTimestamp(absl::ToUnixNanos(t));
}

}  // namespace

void Fill(const LoadedMesh& mesh, int sessions, pb::MeshInfo* out) {
  const Topology& t = *mesh.topology;
  out->set_mesh_id(mesh.id);
  out->set_name(mesh.name);
  out->set_source(mesh.source);
  out->set_vertices(t.num_vertices());
  out->set_edges(t.num_edges());
  out->set_triangles(t.num_triangles());
  out->set_tetrahedra(t.num_tetrahedra());
  out->set_blocks(t.num_blocks());
  out->set_block_size(mesh.block_size);
  for (const PointField& f : mesh.mesh.point_fields) {
    pb::FieldInfo* fi = out->add_fields();
    fi->set_name(f.name);
    fi->set_dtype(f.is_integer ? (f.source_bytes == 4 ? pb::DATA_TYPE_INT32 : pb::DATA_TYPE_INT64)
                               : (f.source_bytes == 4 ? pb::DATA_TYPE_FLOAT32
                                                      : pb::DATA_TYPE_FLOAT64));
    if (!f.values.empty()) {
      const auto [lo, hi] = std::minmax_element(f.values.begin(), f.values.end());
      fi->set_min(*lo);
      fi->set_max(*hi);
    }
  }
  out->set_bytes(mesh.bytes());
  out->set_sessions(sessions);
  *out->mutable_created() = Stamp(mesh.created);
  out->set_load_seconds(mesh.load_seconds);
  out->set_partition_seconds(mesh.partition_seconds);
}

void Fill(Session& s, const std::string& running_job, pb::SessionInfo* out) {
  out->set_session_id(s.id());
  out->set_mesh_id(s.mesh().id);
  out->set_scalar_field(s.scalar_name());
  const SessionOptions& o = s.options();
  out->set_structure(o.structure == StructureKind::kExplicit  ? pb::STRUCTURE_EXPLICIT
                     : o.structure == StructureKind::kCompact ? pb::STRUCTURE_COMPACT
                                                              : pb::STRUCTURE_ACTOPO);
  pb::EngineOptions* e = out->mutable_engine();
  e->set_consumers(o.consumers);
  e->set_producers(o.producers);
  e->set_buffer_ratio(o.buffer_ratio);
  e->set_query_readers(o.query_readers);
  if (o.prefetch) e->set_prefetch(static_cast<pb::Prefetch>(int(*o.prefetch) + 1));
  if (o.precompute) e->set_precompute(static_cast<pb::Precompute>(int(*o.precompute) + 1));
  *out->mutable_created() = Stamp(s.created());
  *out->mutable_last_used() = Stamp(s.last_used());
  out->set_running_job_id(running_job);
}

void Fill(const EngineStats& s, pb::EngineStats* out) {
  out->set_requests(s.access.requests);
  out->set_hits(s.access.hits);
  out->set_misses(s.access.misses);
  out->set_evictions(s.access.evictions);
  out->set_wait_ns(s.access.wait_ns);
  out->set_leader_relations(s.leader_relations);
  out->set_worker_relations(s.worker_relations);
  out->set_consumer_relations(s.consumer_relations);
  out->set_duplicates_avoided(s.duplicates_avoided);
  out->set_producer_busy_ns(s.producer_busy_ns);
  out->set_buffer_bytes(s.buffer_bytes);
  out->set_buffer_peak_bytes(s.buffer_peak_bytes);
}

void Fill(const MemoryStats& m, pb::MemoryStats* out) {
  out->set_static_bytes(m.static_bytes);
  out->set_relation_bytes(m.relation_bytes);
  out->set_relation_peak_bytes(m.relation_peak_bytes);
}

void Pack(const std::string& name, std::span<const int64_t> values, pb::Array* out) {
  out->set_name(name);
  out->set_dtype(pb::DATA_TYPE_INT64);
  out->add_shape(int64_t(values.size()));
  out->set_data(reinterpret_cast<const char*>(values.data()), values.size_bytes());
}

void Pack(const std::string& name, const io::NamedArray& array, pb::Array* out) {
  out->set_name(name);
  out->add_shape(int64_t(array.size()));
  std::visit(
      [&](const auto& v) {
        using T = typename std::decay_t<decltype(v)>::value_type;
        if constexpr (std::is_same_v<T, int32_t>) out->set_dtype(pb::DATA_TYPE_INT32);
        if constexpr (std::is_same_v<T, int8_t>) out->set_dtype(pb::DATA_TYPE_INT8);
        if constexpr (std::is_same_v<T, double>) out->set_dtype(pb::DATA_TYPE_FLOAT64);
        if constexpr (std::is_same_v<T, float>) out->set_dtype(pb::DATA_TYPE_FLOAT32);
        out->set_data(reinterpret_cast<const char*>(v.data()), v.size() * sizeof(T));
      },
      array.values);
}

void PackPoints(const std::string& name, std::span<const double> xyz, pb::Array* out) {
  out->set_name(name);
  out->set_dtype(pb::DATA_TYPE_FLOAT64);
  out->add_shape(int64_t(xyz.size() / 3));
  out->add_shape(3);
  out->set_data(reinterpret_cast<const char*>(xyz.data()), xyz.size_bytes());
}

size_t DataTypeSize(pb::DataType t) {
  switch (t) {
    case pb::DATA_TYPE_FLOAT32: return 4;
    case pb::DATA_TYPE_FLOAT64: return 8;
    case pb::DATA_TYPE_INT8: return 1;
    case pb::DATA_TYPE_INT32: return 4;
    case pb::DATA_TYPE_INT64: return 8;
    case pb::DATA_TYPE_UINT8: return 1;
    default: return 0;
  }
}

absl::StatusOr<std::vector<int64_t>> UnpackIntegers(const pb::Array& array,
                                                    std::string_view field) {
  const size_t size = DataTypeSize(array.dtype());
  if (array.dtype() != pb::DATA_TYPE_INT32 && array.dtype() != pb::DATA_TYPE_INT64) {
    return absl::InvalidArgumentError(absl::StrCat(std::string(field), ".dtype: ",
                                                   pb::DataType_Name(array.dtype()),
                                                   " is not an integer type; use INT32 or INT64"));
  }
  for (int64_t d : array.shape()) {
    if (d < 0) {
      return absl::InvalidArgumentError(
          absl::StrCat(std::string(field), ".shape: negative extent ", d));
    }
  }
  // The extents' product is compared with the values the data holds as it grows, so a hostile
  // shape cannot overflow it.
  const int64_t in_data = int64_t(array.data().size() / size);
  int64_t count = array.shape().empty() ? in_data : 1;
  bool fits = true;
  if (absl::c_find(array.shape(), 0) != array.shape().end()) count = 0;
  for (int64_t d : array.shape()) {
    if (count == 0) break;
    if (count > in_data / d) {
      fits = false;
      break;
    }
    count *= d;
  }
  if (!fits || array.data().size() != size_t(count) * size) {
    return absl::InvalidArgumentError(absl::StrCat(
        std::string(field), ".data: ", array.data().size(), " bytes for shape [",
        absl::StrJoin(array.shape(), ", "), "] of ", size, "-byte values"));
  }
  std::vector<int64_t> out(count);
  const char* p = array.data().data();
  for (int64_t i = 0; i < count; ++i) {
    if (size == 4) {
      int32_t v;
      std::memcpy(&v, p + 4 * i, 4);
      out[i] = v;
    } else {
      std::memcpy(&out[i], p + 8 * i, 8);
    }
  }
  return out;
}

}  // namespace actopo::service
