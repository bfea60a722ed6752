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
  if (t.has_faces()) {  // built on their first need (LoadedMesh::EnsureFaces)
    out->set_edges(t.num_edges());
    out->set_triangles(t.num_triangles());
  }
  out->set_tetrahedra(t.num_tetrahedra());
  out->set_blocks(t.num_blocks());
  out->set_block_size(mesh.block_size);
  for (const FieldSet::Ref& held : mesh.fields.List()) {
    const PointField& f = held->field;
    pb::FieldInfo* fi = out->add_fields();
    fi->set_name(f.name);
    fi->set_dtype(f.is_integer
                      ? (f.source_bytes == 4 ? pb::DATA_TYPE_INT32 : pb::DATA_TYPE_INT64)
                      : (f.source_bytes == 4 ? pb::DATA_TYPE_FLOAT32 : pb::DATA_TYPE_FLOAT64));
    fi->set_min(held->min);
    fi->set_max(held->max);
    if (held->time) fi->set_time(*held->time);
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
  out->set_waits_abandoned(s.waits_abandoned);
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

// One node of a summary's JSON tree as a protobuf Value: objects to structs, arrays to lists,
// numbers to doubles (as google.protobuf.Value holds them), strings and booleans as they are.
void ToValue(const nlohmann::ordered_json& json, google::protobuf::Value* out) {
  using Type = nlohmann::ordered_json::value_t;
  switch (json.type()) {
    case Type::object: {
      Struct* fields = out->mutable_struct_value();
      for (const auto& [key, value] : json.items())
        ToValue(value, &(*fields->mutable_fields())[key]);
      break;
    }
    case Type::array: {
      google::protobuf::ListValue* list = out->mutable_list_value();
      for (const auto& value : json) ToValue(value, list->add_values());
      break;
    }
    case Type::string: out->set_string_value(json.get<std::string>()); break;
    case Type::boolean: out->set_bool_value(json.get<bool>()); break;
    case Type::number_integer:
    case Type::number_unsigned:
    case Type::number_float: out->set_number_value(json.get<double>()); break;
    default: out->set_null_value(google::protobuf::NULL_VALUE); break;
  }
}

}  // namespace

void FillStruct(const nlohmann::ordered_json& json, Struct* out) {
  out->Clear();
  for (const auto& [key, value] : json.items()) ToValue(value, &(*out->mutable_fields())[key]);
}

void FillSummary(const AlgorithmResult& result, const Topology& topology,
                 const SummaryOptions& options, Struct* out) {
  // Summarize spells the summary's keys once, for actopo-bench's JSON and for the wire; its tree
  // is copied node by node, without a text round trip.
  FillStruct(Summarize(result, topology, options), out);
}

std::string_view Describe(const std::string& name, std::span<const int64_t> values,
                          pb::Array* out) {
  out->set_name(name);
  out->set_dtype(pb::DATA_TYPE_INT64);
  out->add_shape(int64_t(values.size()));
  return {reinterpret_cast<const char*>(values.data()), values.size_bytes()};
}

std::string_view Describe(const std::string& name, const io::NamedArray& array, pb::Array* out) {
  out->set_name(name);
  out->add_shape(int64_t(array.size()));
  if (array.components > 1) out->add_shape(array.components);
  return std::visit(
      [&](const auto& v) {
        using T = typename std::decay_t<decltype(v)>::value_type;
        if constexpr (std::is_same_v<T, int32_t>) out->set_dtype(pb::DATA_TYPE_INT32);
        if constexpr (std::is_same_v<T, int8_t>) out->set_dtype(pb::DATA_TYPE_INT8);
        if constexpr (std::is_same_v<T, double>) out->set_dtype(pb::DATA_TYPE_FLOAT64);
        if constexpr (std::is_same_v<T, float>) out->set_dtype(pb::DATA_TYPE_FLOAT32);
        return std::string_view(reinterpret_cast<const char*>(v.data()), v.size() * sizeof(T));
      },
      array.values);
}

std::string_view DescribePoints(const std::string& name, std::span<const double> xyz,
                                pb::Array* out) {
  out->set_name(name);
  out->set_dtype(pb::DATA_TYPE_FLOAT64);
  out->add_shape(int64_t(xyz.size() / 3));
  out->add_shape(3);
  return {reinterpret_cast<const char*>(xyz.data()), xyz.size_bytes()};
}

void Pack(const std::string& name, std::span<const int64_t> values, pb::Array* out) {
  const std::string_view bytes = Describe(name, values, out);
  out->set_data(bytes.data(), bytes.size());
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
