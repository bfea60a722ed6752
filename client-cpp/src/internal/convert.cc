#include "src/internal/convert.h"

#include <bit>
#include <cstring>

#include "absl/strings/str_cat.h"
#include "src/internal/names.h"

namespace actopo::client::internal {

// The wire is little-endian and arrays are copied byte for byte.
static_assert(std::endian::native == std::endian::little,
              "the actopo client supports little-endian hosts only");

namespace {

std::chrono::system_clock::time_point FromProto(const google::protobuf::Timestamp& t) {
  return std::chrono::system_clock::time_point(
      std::chrono::duration_cast<std::chrono::system_clock::duration>(
          std::chrono::seconds(t.seconds()) + std::chrono::nanoseconds(t.nanos())));
}

Counter FromProto(const v1::Counter& c) { return Counter{.count = c.count(), .ns = c.ns()}; }

}  // namespace

ServerInfo FromProto(const v1::GetServerInfoResponse& info) {
  ServerInfo out;
  out.version = info.version();
  out.library_versions.insert(info.library_versions().begin(), info.library_versions().end());
  out.algorithms.assign(info.algorithms().begin(), info.algorithms().end());
  out.relations.assign(info.relations().begin(), info.relations().end());
  out.samples.assign(info.samples().begin(), info.samples().end());
  const v1::ServerLimits& l = info.limits();
  out.limits = ServerLimits{
      .max_meshes = l.max_meshes(),
      .max_sessions = l.max_sessions(),
      .max_engine_threads = l.max_engine_threads(),
      .memory_budget_bytes = l.memory_budget_bytes(),
      .max_message_bytes = l.max_message_bytes(),
      .max_batch_size = l.max_batch_size(),
      .session_idle_timeout_seconds = l.session_idle_timeout_seconds(),
      .upload_budget_bytes = l.upload_budget_bytes(),
      .upload_timeout_seconds = l.upload_timeout_seconds(),
      .max_uploads = l.max_uploads(),
  };
  return out;
}

MeshInfo FromProto(const v1::MeshInfo& mesh) {
  MeshInfo out;
  out.mesh_id = mesh.mesh_id();
  out.name = mesh.name();
  out.source = mesh.source();
  out.vertices = mesh.vertices();
  if (mesh.has_edges()) out.edges = mesh.edges();
  if (mesh.has_triangles()) out.triangles = mesh.triangles();
  out.tetrahedra = mesh.tetrahedra();
  out.blocks = mesh.blocks();
  out.block_size = mesh.block_size();
  for (const v1::FieldInfo& f : mesh.fields()) {
    out.fields.push_back(FieldInfo{.name = f.name(),
                                   .dtype = FromProto(f.dtype()),
                                   .min = f.min(),
                                   .max = f.max(),
                                   .time = f.has_time() ? std::optional(f.time()) : std::nullopt});
  }
  out.bytes = mesh.bytes();
  out.sessions = mesh.sessions();
  out.created = FromProto(mesh.created());
  out.load_seconds = mesh.load_seconds();
  out.partition_seconds = mesh.partition_seconds();
  return out;
}

UploadStatus FromProto(const v1::UploadStatus& upload) {
  UploadStatus out;
  out.upload_id = upload.upload_id();
  for (const v1::UploadFileInfo& f : upload.files()) {
    out.files.push_back(UploadFileInfo{.path = f.path(), .size = f.size(), .sha256 = f.sha256()});
  }
  out.received_bytes.assign(upload.received_bytes().begin(), upload.received_bytes().end());
  out.complete = upload.complete();
  out.expires_in_seconds = upload.expires_in_seconds();
  return out;
}

SessionInfo FromProto(const v1::SessionInfo& session) {
  SessionInfo out;
  out.session_id = session.session_id();
  out.mesh_id = session.mesh_id();
  out.scalar_field = session.scalar_field();
  out.structure = FromProto(session.structure());
  const v1::EngineOptions& e = session.engine();
  out.consumers = e.consumers();
  out.producers = e.producers();
  out.buffer_ratio = e.buffer_ratio();
  out.prefetch = FromProto(e.prefetch());
  out.precompute = FromProto(e.precompute());
  out.created = FromProto(session.created());
  out.last_used = FromProto(session.last_used());
  out.running_job_id = session.running_job_id();
  return out;
}

EngineStats FromProto(const v1::EngineStats& e) {
  return EngineStats{
      .requests = e.requests(),
      .hits = e.hits(),
      .misses = e.misses(),
      .evictions = e.evictions(),
      .wait_ns = e.wait_ns(),
      .leader_relations = e.leader_relations(),
      .worker_relations = e.worker_relations(),
      .consumer_relations = e.consumer_relations(),
      .duplicates_avoided = e.duplicates_avoided(),
      .producer_busy_ns = e.producer_busy_ns(),
      .buffer_bytes = e.buffer_bytes(),
      .buffer_peak_bytes = e.buffer_peak_bytes(),
      .waits_abandoned = e.waits_abandoned(),
  };
}

MemoryStats FromProto(const v1::MemoryStats& m) {
  return MemoryStats{
      .static_bytes = m.static_bytes(),
      .relation_bytes = m.relation_bytes(),
      .relation_peak_bytes = m.relation_peak_bytes(),
      .process_rss_bytes = m.process_rss_bytes(),
  };
}

SessionStats FromProto(const v1::GetSessionStatsResponse& stats) {
  return SessionStats{
      .engine = FromProto(stats.engine()),
      .memory = FromProto(stats.memory()),
      .relation_queries = FromProto(stats.relation_queries()),
      .jobs = FromProto(stats.jobs()),
      .preprocess_seconds = stats.preprocess_seconds(),
  };
}

JobStats FromProto(const v1::JobStats& stats) {
  return JobStats{.run_seconds = stats.run_seconds(),
                  .engine = FromProto(stats.engine()),
                  .memory = FromProto(stats.memory()),
                  .faces_seconds = stats.faces_seconds()};
}

v1::PartitionOptions ToProto(const PartitionOptions& partition) {
  v1::PartitionOptions out;
  out.set_block_size(partition.block_size);
  out.set_block_label_field(partition.block_label_field);
  return out;
}

void PackInt64(std::span<const int64_t> values, std::span<const int64_t> shape, v1::Array* out) {
  out->set_dtype(v1::DATA_TYPE_INT64);
  out->mutable_shape()->Add(shape.begin(), shape.end());
  out->set_data(reinterpret_cast<const char*>(values.data()), values.size_bytes());
}

absl::StatusOr<std::vector<int64_t>> UnpackInt64(const v1::Array& array, std::string_view field) {
  if (array.dtype() != v1::DATA_TYPE_INT64 || array.data().size() % sizeof(int64_t) != 0) {
    return absl::InternalError(absl::StrCat(std::string(field), ": the server sent ",
                                            v1::DataType_Name(array.dtype()), " with ",
                                            array.data().size(), " bytes, not an int64 array"));
  }
  std::vector<int64_t> values(array.data().size() / sizeof(int64_t));
  if (!values.empty()) std::memcpy(values.data(), array.data().data(), array.data().size());
  return values;
}

}  // namespace actopo::client::internal
