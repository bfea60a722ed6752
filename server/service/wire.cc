#include "server/service/wire.h"

#include <bit>
#include <cstring>

#include "absl/algorithm/container.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "google/protobuf/util/time_util.h"
#include "server/core/parallel.h"
#include "server/core/status_macros.h"

namespace actopo::service {

static_assert(std::endian::native == std::endian::little,
              "arrays travel as raw little-endian bytes");

grpc::Status ToGrpcStatus(const absl::Status& status) {
  if (status.ok()) return grpc::Status::OK;
  return grpc::Status(static_cast<grpc::StatusCode>(status.code()), std::string(status.message()));
}

namespace {

static_assert(std::size(kRelationMapping) == kNumRelations);

template <class P, class C, size_t N>
std::optional<C> CoreValue(const EnumMapping<P, C> (&mapping)[N], P proto) {
  for (const auto& row : mapping) {
    if (row.proto == proto) return row.core;
  }
  return std::nullopt;
}

// _UNSPECIFIED for a core value the API does not name.
template <class P, class C, size_t N>
P ProtoValue(const EnumMapping<P, C> (&mapping)[N], C core) {
  for (const auto& row : mapping) {
    if (row.core == core) return row.proto;
  }
  return P{};
}

// "RELATION_VERTEX_EDGES", or the number of a value the API does not define.
template <class P>
std::string ValueName(P value) {
  const google::protobuf::EnumValueDescriptor* d =
      google::protobuf::GetEnumDescriptor<P>()->FindValueByNumber(int(value));
  return d != nullptr ? d->name() : std::to_string(int(value));
}

// `hint()` (what to set instead) is only built for an error: relations are converted on every
// query.
template <class P, class C, size_t N, class Hint>
absl::StatusOr<C> FromProtoOrError(const EnumMapping<P, C> (&mapping)[N], P proto,
                                   const char* field, const char* what, Hint hint) {
  if (std::optional<C> core = CoreValue(mapping, proto)) return *core;
  return absl::InvalidArgumentError(
      absl::StrCat(field, ": ", ValueName(proto), " is not ", what, hint()));
}

std::string NoHint() { return ""; }

}  // namespace

absl::StatusOr<Relation> FromProto(pb::Relation r) {
  return FromProtoOrError(kRelationMapping, r, "relation", "a relation", [] {
    return absl::StrCat("; set one of ", ValueName(std::begin(kRelationMapping)->proto), " ... ",
                        ValueName(std::rbegin(kRelationMapping)->proto));
  });
}

absl::StatusOr<Algorithm> FromProto(pb::Algorithm a) {
  return FromProtoOrError(kAlgorithmMapping, a, "algorithm", "an algorithm", [] {
    std::string hint = "; set ";
    for (size_t i = 0; i < std::size(kAlgorithmMapping); ++i) {
      const char* separator = i == 0 ? "" : i + 1 < std::size(kAlgorithmMapping) ? ", " : " or ";
      absl::StrAppend(&hint, separator, ValueName(kAlgorithmMapping[i].proto));
    }
    return hint;
  });
}

absl::StatusOr<StructureKind> FromProto(pb::Structure s) {
  return FromProtoOrError(kStructureMapping, s, "structure", "a structure", NoHint);
}

absl::StatusOr<Prefetch> FromProto(pb::Prefetch p) {
  return FromProtoOrError(kPrefetchMapping, p, "engine.prefetch", "a prefetch mode", NoHint);
}

absl::StatusOr<Precompute> FromProto(pb::Precompute p) {
  return FromProtoOrError(kPrecomputeMapping, p, "engine.precompute", "a scope", NoHint);
}

pb::Relation ToProto(Relation r) { return ProtoValue(kRelationMapping, r); }
pb::Algorithm ToProto(Algorithm a) { return ProtoValue(kAlgorithmMapping, a); }
pb::Structure ToProto(StructureKind s) { return ProtoValue(kStructureMapping, s); }
pb::Prefetch ToProto(Prefetch p) { return ProtoValue(kPrefetchMapping, p); }
pb::Precompute ToProto(Precompute p) { return ProtoValue(kPrecomputeMapping, p); }

absl::StatusOr<SessionOptions> FromProto(const pb::OpenSessionRequest& r) {
  SessionOptions o;
  o.scalar_field = r.scalar_field();
  StructureOptions& s = o.structure;
  // Not set: ACTOPO.
  if (r.structure() != pb::STRUCTURE_UNSPECIFIED) {
    ASSIGN_OR_RETURN(s.kind, FromProto(r.structure()));
  }
  // Zeros and unset modes keep the module's defaults: from the cores, or per algorithm.
  const pb::EngineOptions& e = r.engine();
  s.consumers = e.consumers();
  s.producers = e.producers();
  if (e.buffer_ratio() != 0) s.buffer_ratio = e.buffer_ratio();
  s.query_readers = e.query_readers();
  if (e.prefetch() != pb::PREFETCH_UNSPECIFIED) {
    ASSIGN_OR_RETURN(s.prefetch, FromProto(e.prefetch()));
  }
  if (e.precompute() != pb::PRECOMPUTE_UNSPECIFIED) {
    ASSIGN_OR_RETURN(s.precompute, FromProto(e.precompute()));
  }
  s = WithDefaults(s);
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
    fi->set_dtype(f.is_integer
                      ? (f.source_bytes == 4 ? pb::DATA_TYPE_INT32 : pb::DATA_TYPE_INT64)
                      : (f.source_bytes == 4 ? pb::DATA_TYPE_FLOAT32 : pb::DATA_TYPE_FLOAT64));
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
  const StructureOptions& o = s.options().structure;
  out->set_structure(ToProto(o.kind));
  pb::EngineOptions* e = out->mutable_engine();
  e->set_consumers(o.consumers);
  e->set_producers(o.producers);
  e->set_buffer_ratio(o.buffer_ratio);
  e->set_query_readers(o.query_readers);
  if (o.prefetch) e->set_prefetch(ToProto(*o.prefetch));
  if (o.precompute) e->set_precompute(ToProto(*o.precompute));
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

namespace {

using google::protobuf::Struct;

void SetNumber(Struct* s, const std::string& key, double number) {
  (*s->mutable_fields())[key].set_number_value(number);
}

void SetString(Struct* s, const std::string& key, std::string text) {
  (*s->mutable_fields())[key].set_string_value(std::move(text));
}

void SetList(Struct* s, const std::string& key, std::span<const int64_t> numbers) {
  google::protobuf::ListValue* list = (*s->mutable_fields())[key].mutable_list_value();
  for (int64_t n : numbers) list->add_values()->set_number_value(double(n));
}

Struct* SetStruct(Struct* s, const std::string& key) {
  return (*s->mutable_fields())[key].mutable_struct_value();
}

void FillTopoRelations(const TopoRelationsResult& r, Struct* out) {
  Struct* totals = SetStruct(out, "relation_totals");
  for (Relation rel : TopoRelationsSweeps()) {
    SetNumber(totals, std::string(RelationName(rel)), double(r.totals[Index(rel)]));
  }
  SetString(out, "checksum", r.checksum_hex());
}

void FillCriticalPoints(const CriticalPointsResult& r, Struct* out) {
  Struct* counts = SetStruct(out, "counts");
  const auto count = [&](CriticalType t) { return double(r.counts[int(t)]); };
  SetNumber(counts, "minimum", count(CriticalType::kMinimum));
  SetNumber(counts, "saddle1", count(CriticalType::kSaddle1));
  SetNumber(counts, "saddle2", count(CriticalType::kSaddle2));
  SetNumber(counts, "degenerate", count(CriticalType::kDegenerate));
  SetNumber(counts, "maximum", count(CriticalType::kMaximum));
  SetString(out, "vertices_sha256", r.VerticesDigest());
}

void FillDiscreteGradient(const DiscreteGradientResult& r, const Topology& topology, Struct* out) {
  SetList(out, "critical_cells", r.critical_cells);
  SetList(out, "pairs_count", r.pairs);
  SetString(out, "critical_cells_sha256", r.CriticalCellsDigest(topology));
  SetString(out, "pairs_sha256", r.PairsDigest(topology));
}

void FillMorseSmale(const MorseSmaleResult& r, Struct* out) {
  SetList(out, "critical_cells", r.gradient.critical_cells);
  Struct* separatrices = SetStruct(out, "separatrices");
  SetNumber(separatrices, "descending", double(r.CountSeparatrices(SeparatrixType::kDescending)));
  SetNumber(separatrices, "ascending", double(r.CountSeparatrices(SeparatrixType::kAscending)));
  SetNumber(separatrices, "saddle_connectors",
            double(r.CountSeparatrices(SeparatrixType::kSaddleConnector)));
  SetNumber(separatrices, "segments", double(r.Segments()));
  Struct* regions = SetStruct(out, "regions");
  SetNumber(regions, "descending", double(MorseSmaleResult::Regions(r.descending)));
  SetNumber(regions, "ascending", double(MorseSmaleResult::Regions(r.ascending)));
  SetNumber(regions, "morse_smale", double(MorseSmaleResult::Regions(r.morse_smale)));
  Struct* sizes = SetStruct(out, "manifold_size_sum");
  SetNumber(sizes, "minima", double(absl::c_accumulate(r.minimum_sizes, int64_t{0})));
  SetNumber(sizes, "maxima", double(absl::c_accumulate(r.maximum_sizes, int64_t{0})));
  Struct* unlabelled = SetStruct(out, "unlabelled_vertices");
  SetNumber(unlabelled, "descending", double(absl::c_count(r.descending, -1)));
  SetNumber(unlabelled, "ascending", double(absl::c_count(r.ascending, -1)));
  SetNumber(unlabelled, "morse_smale", double(absl::c_count(r.morse_smale, -1)));
  Struct* digests = SetStruct(out, "segmentation_sha256");
  SetString(digests, "descending", MorseSmaleResult::SegmentationDigest(r.descending));
  SetString(digests, "ascending", MorseSmaleResult::SegmentationDigest(r.ascending));
  SetString(digests, "morse_smale", MorseSmaleResult::SegmentationDigest(r.morse_smale));
}

}  // namespace

void FillSummary(const AlgorithmResult& result, const Topology& topology, Struct* out) {
  out->Clear();
  std::visit(
      [&](const auto& r) {
        using T = std::decay_t<decltype(r)>;
        if constexpr (std::is_same_v<T, TopoRelationsResult>) FillTopoRelations(r, out);
        if constexpr (std::is_same_v<T, CriticalPointsResult>) FillCriticalPoints(r, out);
        if constexpr (std::is_same_v<T, DiscreteGradientResult>) {
          FillDiscreteGradient(r, topology, out);
        }
        if constexpr (std::is_same_v<T, MorseSmaleResult>) FillMorseSmale(r, out);
      },
      result);
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
    return absl::InvalidArgumentError(absl::StrCat(std::string(field),
                                                   ".dtype: ", pb::DataType_Name(array.dtype()),
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
    return absl::InvalidArgumentError(
        absl::StrCat(std::string(field), ".data: ", array.data().size(), " bytes for shape [",
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
