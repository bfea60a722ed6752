// Client: connection, server info, meshes, fields and sessions (unary calls).
#include "actopo/client.h"

#include <cmath>
#include <functional>

#include "absl/strings/str_cat.h"
#include "src/internal/convert.h"
#include "src/internal/core.h"
#include "src/internal/load.h"
#include "src/internal/names.h"

namespace actopo::client {

using internal::FromProto;
using internal::LoadWithProgress;
using internal::ToProto;

absl::StatusOr<std::unique_ptr<Client>> Client::Connect(std::string_view target,
                                                        const ClientOptions& options) {
  ACTOPO_ASSIGN_OR_RETURN(std::shared_ptr<internal::Core> core,
                          internal::NewCore(std::string(target), options));
  return std::unique_ptr<Client>(new Client(std::move(core)));
}

Client::Client(std::shared_ptr<internal::Core> core) : core_(std::move(core)) {}

Client::~Client() = default;

const std::string& Client::target() const { return core_->target; }

const std::string& Client::affinity_key() const { return core_->options.affinity_key; }

absl::StatusOr<ServerInfo> Client::GetServerInfo() {
  ACTOPO_ASSIGN_OR_RETURN(v1::GetServerInfoResponse response,
                          core_->Unary(&v1::TopologyService::Stub::GetServerInfo,
                                       v1::GetServerInfoRequest(), core_->QuickContext()));
  ServerInfo info = FromProto(response);
  core_->max_batch_size = info.limits.max_batch_size;
  return info;
}

absl::StatusOr<int64_t> Client::MaxBatchSize() {
  if (core_->max_batch_size.load() <= 0) {
    ACTOPO_RETURN_IF_ERROR(GetServerInfo().status());
  }
  // A server that reports no limit gets batches of a size any server takes.
  const int64_t limit = core_->max_batch_size.load();
  return limit > 0 ? limit : int64_t{100'000};
}

// ---------------------------------------------------------------------------------------------
// Meshes.

namespace {

absl::Status CheckPartition(const PartitionOptions& partition) {
  if (partition.block_size < 0) {
    return absl::InvalidArgumentError(
        absl::StrCat("partition.block_size: ", partition.block_size, " is negative"));
  }
  return absl::OkStatus();
}

absl::StatusOr<v1::LoadMeshRequest> LoadRequest(std::string_view path,
                                                const PartitionOptions& partition) {
  ACTOPO_RETURN_IF_ERROR(CheckPartition(partition));
  constexpr std::string_view kSample = "sample:";
  v1::LoadMeshRequest request;
  if (path.substr(0, kSample.size()) == kSample) {
    request.set_sample(std::string(path.substr(kSample.size())));
  } else {
    request.set_path(std::string(path));
  }
  *request.mutable_partition() = ToProto(partition);
  return request;
}

// The times are checked here as the server checks them, with its words; the paths (empty,
// missing, outside the data directory) only the server can judge.
absl::StatusOr<v1::LoadMeshRequest> SeriesRequest(const std::vector<std::string>& paths,
                                                  const std::vector<double>& times,
                                                  const PartitionOptions& partition) {
  ACTOPO_RETURN_IF_ERROR(CheckPartition(partition));
  if (!times.empty() && times.size() != paths.size()) {
    return absl::InvalidArgumentError(absl::StrCat("files.times: ", times.size(), " values for ",
                                                   paths.size(),
                                                   " paths; give one per path, or none"));
  }
  v1::LoadMeshRequest request;
  v1::FileSeries* files = request.mutable_files();  // set even when empty, for the server to say
  for (const std::string& path : paths) files->add_paths(path);
  for (size_t k = 0; k < times.size(); ++k) {
    if (!std::isfinite(times[k])) {
      return absl::InvalidArgumentError(
          absl::StrCat("files.times[", k, "]: ", times[k], " is not finite"));
    }
    files->add_times(times[k]);
  }
  *request.mutable_partition() = ToProto(partition);
  return request;
}

absl::StatusOr<MeshInfo> Load(const internal::Core& core, const v1::LoadMeshRequest& request) {
  ACTOPO_ASSIGN_OR_RETURN(
      v1::LoadMeshResponse response,
      core.Unary(&v1::TopologyService::Stub::LoadMesh, request, core.MeshContext()));
  return FromProto(response.mesh());
}

}  // namespace

absl::StatusOr<MeshInfo> internal::LoadWithProgress(const internal::Core& core,
                                                    v1::LoadMeshRequest load,
                                                    const LoadOptions& options,
                                                    const internal::OnCancel& on_cancel) {
  v1::LoadMeshWithProgressRequest request;
  *request.mutable_load() = std::move(load);
  if (options.cancel.cancelled()) return absl::CancelledError("load: cancelled before it started");
  std::unique_ptr<grpc::ClientContext> context =
      core.Context(options.timeout.count() > 0 ? options.timeout : core.options.mesh_timeout);
  grpc::ClientContext* raw = context.get();
  std::shared_ptr<void> registration = on_cancel([raw] { raw->TryCancel(); });
  std::unique_ptr<grpc::ClientReader<v1::LoadMeshWithProgressResponse>> reader =
      core.stub->LoadMeshWithProgress(raw, request);
  std::optional<MeshInfo> mesh;
  v1::LoadMeshWithProgressResponse response;
  try {
    while (reader->Read(&response)) {
      if (response.has_mesh()) {
        mesh = FromProto(response.mesh());
      } else if (response.has_progress() && options.progress) {
        const v1::LoadProgress& p = response.progress();
        options.progress({p.phase(), p.fraction(), p.elapsed_seconds()});
      }
    }
  } catch (...) {  // from the callback: stop the load before the stack unwinds
    raw->TryCancel();
    while (reader->Read(&response)) {
    }
    reader->Finish();
    throw;
  }
  const grpc::Status status = reader->Finish();
  registration.reset();  // before the context goes
  ACTOPO_RETURN_IF_ERROR(internal::FromGrpc(status));
  if (!mesh) return absl::DataLossError("load: the stream ended without the mesh");
  return *std::move(mesh);
}

absl::StatusOr<MeshInfo> Client::LoadMesh(std::string_view path,
                                          const PartitionOptions& partition) {
  ACTOPO_ASSIGN_OR_RETURN(v1::LoadMeshRequest request, LoadRequest(path, partition));
  return Load(*core_, request);
}

absl::StatusOr<MeshInfo> Client::LoadMeshWithProgress(std::string_view path,
                                                      const LoadOptions& options) {
  ACTOPO_ASSIGN_OR_RETURN(v1::LoadMeshRequest request, LoadRequest(path, options.partition));
  return LoadWithProgress(*core_, std::move(request), options, [&](std::function<void()> f) {
    return options.cancel.OnCancel(std::move(f));
  });
}

absl::StatusOr<MeshInfo> Client::LoadSeries(const std::vector<std::string>& paths,
                                            const std::vector<double>& times,
                                            const PartitionOptions& partition) {
  ACTOPO_ASSIGN_OR_RETURN(v1::LoadMeshRequest request, SeriesRequest(paths, times, partition));
  return Load(*core_, request);
}

absl::StatusOr<MeshInfo> Client::LoadSeriesWithProgress(const std::vector<std::string>& paths,
                                                        const std::vector<double>& times,
                                                        const LoadOptions& options) {
  ACTOPO_ASSIGN_OR_RETURN(v1::LoadMeshRequest request,
                          SeriesRequest(paths, times, options.partition));
  return LoadWithProgress(*core_, std::move(request), options, [&](std::function<void()> f) {
    return options.cancel.OnCancel(std::move(f));
  });
}

absl::StatusOr<std::vector<MeshInfo>> Client::ListMeshes() {
  ACTOPO_ASSIGN_OR_RETURN(v1::ListMeshesResponse response,
                          core_->Unary(&v1::TopologyService::Stub::ListMeshes,
                                       v1::ListMeshesRequest(), core_->QuickContext()));
  std::vector<MeshInfo> meshes;
  for (const v1::MeshInfo& m : response.meshes()) meshes.push_back(FromProto(m));
  return meshes;
}

absl::StatusOr<MeshInfo> Client::GetMesh(std::string_view mesh_id, bool count_faces) {
  v1::GetMeshRequest request;
  request.set_mesh_id(std::string(mesh_id));
  request.set_count_faces(count_faces);
  ACTOPO_ASSIGN_OR_RETURN(v1::GetMeshResponse response,
                          core_->Unary(&v1::TopologyService::Stub::GetMesh, request,
                                       count_faces ? core_->MeshContext() : core_->QuickContext()));
  return FromProto(response.mesh());
}

absl::Status Client::DeleteMesh(std::string_view mesh_id) {
  v1::DeleteMeshRequest request;
  request.set_mesh_id(std::string(mesh_id));
  return core_->Unary(&v1::TopologyService::Stub::DeleteMesh, request, core_->QuickContext())
      .status();
}

absl::StatusOr<MeshInfo> Client::DeleteField(std::string_view mesh_id, std::string_view name) {
  v1::DeleteFieldRequest request;
  request.set_mesh_id(std::string(mesh_id));
  request.set_name(std::string(name));
  ACTOPO_ASSIGN_OR_RETURN(
      v1::DeleteFieldResponse response,
      core_->Unary(&v1::TopologyService::Stub::DeleteField, request, core_->QuickContext()));
  return FromProto(response.mesh());
}

// ---------------------------------------------------------------------------------------------
// Sessions.

absl::StatusOr<SessionInfo> Client::OpenSession(std::string_view mesh_id,
                                                const SessionOptions& options) {
  v1::OpenSessionRequest request;
  request.set_mesh_id(std::string(mesh_id));
  request.set_scalar_field(options.scalar);
  request.set_structure(ToProto(options.structure));
  v1::EngineOptions* engine = request.mutable_engine();
  engine->set_consumers(options.consumers);
  engine->set_producers(options.producers);
  engine->set_buffer_ratio(options.buffer_ratio);
  engine->set_prefetch(ToProto(options.prefetch));
  engine->set_precompute(ToProto(options.precompute));
  ACTOPO_ASSIGN_OR_RETURN(
      v1::OpenSessionResponse response,
      core_->Unary(&v1::TopologyService::Stub::OpenSession, request, core_->MeshContext()));
  return FromProto(response.session());
}

absl::StatusOr<SessionInfo> Client::GetSession(std::string_view session_id) {
  v1::GetSessionRequest request;
  request.set_session_id(std::string(session_id));
  ACTOPO_ASSIGN_OR_RETURN(
      v1::GetSessionResponse response,
      core_->Unary(&v1::TopologyService::Stub::GetSession, request, core_->QuickContext()));
  return FromProto(response.session());
}

absl::StatusOr<std::vector<SessionInfo>> Client::ListSessions() {
  ACTOPO_ASSIGN_OR_RETURN(v1::ListSessionsResponse response,
                          core_->Unary(&v1::TopologyService::Stub::ListSessions,
                                       v1::ListSessionsRequest(), core_->QuickContext()));
  std::vector<SessionInfo> sessions;
  for (const v1::SessionInfo& s : response.sessions()) sessions.push_back(FromProto(s));
  return sessions;
}

absl::Status Client::CloseSession(std::string_view session_id) {
  v1::CloseSessionRequest request;
  request.set_session_id(std::string(session_id));
  return core_->Unary(&v1::TopologyService::Stub::CloseSession, request, core_->QuickContext())
      .status();
}

absl::StatusOr<SessionStats> Client::Stats(std::string_view session_id) {
  v1::GetSessionStatsRequest request;
  request.set_session_id(std::string(session_id));
  ACTOPO_ASSIGN_OR_RETURN(
      v1::GetSessionStatsResponse response,
      core_->Unary(&v1::TopologyService::Stub::GetSessionStats, request, core_->QuickContext()));
  return FromProto(response);
}

absl::Status Client::CancelJob(std::string_view job_id) {
  v1::CancelJobRequest request;
  request.set_job_id(std::string(job_id));
  return core_->Unary(&v1::TopologyService::Stub::CancelJob, request, core_->QuickContext())
      .status();
}

}  // namespace actopo::client
