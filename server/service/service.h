// The actopo.v1.TopologyService implementation (gRPC callback API). Every call's work runs on an
// executor the service owns (executor.h), never on gRPC's threads: loading, uploading and
// opening sessions on `background`, cancellable (service_meshes.cc); relation answers, single,
// batched and streamed, on `relations`; jobs on `jobs` (service_streams.cc). Only bookkeeping
// calls that take microseconds and wait for nothing are answered inline (service_unary.cc).
#ifndef ACTOPO_SERVER_SERVICE_SERVICE_H_
#define ACTOPO_SERVER_SERVICE_SERVICE_H_

#include <atomic>
#include <functional>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "actopo/v1/topology_service.grpc.pb.h"
#include "server/core/progress.h"
#include "server/service/executor.h"
#include "server/service/memory_budget.h"
#include "server/service/mesh_registry.h"
#include "server/service/metrics.h"
#include "server/service/reactor_host.h"
#include "server/service/session_manager.h"
#include "server/service/upload_spool.h"

namespace actopo::service {

struct ServiceLimits {
  int max_batch_size = 1 << 20;
  int64_t max_message_bytes = 64 << 20;
  // Reported by GetServerInfo (enforced by the registry and the session manager).
  int max_meshes = 0;
  int max_sessions = 0;
  int max_engine_threads = 0;
  int64_t session_idle_timeout_seconds = 0;
  int64_t upload_budget_bytes = 0;
  int64_t upload_timeout_seconds = 0;
  int max_uploads = 0;
};

// The threads of the service's executors (Server::Start sizes them from the cores and
// --max-engine-threads).
struct ServiceThreads {
  int background = 4;  // loads, uploads, openings: each uses every core inside
  int relations = 2;   // relation answers: one per core
  int jobs = 64;       // algorithm runs: each holds at least one engine thread while it runs
};

class TopologyServiceImpl final : public v1::TopologyService::CallbackService, private ReactorHost {
 public:
  // `before_work`: tests only (ServerOptions::before_work); may be empty.
  TopologyServiceImpl(MeshRegistry* meshes, SessionManager* sessions, UploadSpool* spool,
                      MemoryBudget* budget, Metrics* metrics, ServiceLimits limits,
                      ServiceThreads threads, std::string token,
                      std::function<void(std::string_view)> before_work);

  // Stop accepting work (UNAVAILABLE) and cancel running jobs; health is set by the server.
  void Drain();
  bool draining() const override { return draining_.load(); }

  grpc::ServerUnaryReactor* GetServerInfo(grpc::CallbackServerContext*,
                                          const v1::GetServerInfoRequest*,
                                          v1::GetServerInfoResponse*) override;
  grpc::ServerUnaryReactor* LoadMesh(grpc::CallbackServerContext*, const v1::LoadMeshRequest*,
                                     v1::LoadMeshResponse*) override;
  grpc::ServerWriteReactor<v1::LoadMeshWithProgressResponse>* LoadMeshWithProgress(
      grpc::CallbackServerContext*, const v1::LoadMeshWithProgressRequest*) override;
  grpc::ServerWriteReactor<v1::DownloadMeshResponse>* DownloadMesh(
      grpc::CallbackServerContext*, const v1::DownloadMeshRequest*) override;
  grpc::ServerReadReactor<v1::UploadMeshRequest>* UploadMesh(grpc::CallbackServerContext*,
                                                             v1::UploadMeshResponse*) override;
  grpc::ServerUnaryReactor* CreateUpload(grpc::CallbackServerContext*,
                                         const v1::CreateUploadRequest*,
                                         v1::CreateUploadResponse*) override;
  grpc::ServerReadReactor<v1::WriteUploadRequest>* WriteUpload(grpc::CallbackServerContext*,
                                                               v1::WriteUploadResponse*) override;
  grpc::ServerUnaryReactor* GetUpload(grpc::CallbackServerContext*, const v1::GetUploadRequest*,
                                      v1::GetUploadResponse*) override;
  grpc::ServerUnaryReactor* DeleteUpload(grpc::CallbackServerContext*,
                                         const v1::DeleteUploadRequest*,
                                         v1::DeleteUploadResponse*) override;
  grpc::ServerUnaryReactor* ListMeshes(grpc::CallbackServerContext*, const v1::ListMeshesRequest*,
                                       v1::ListMeshesResponse*) override;
  grpc::ServerUnaryReactor* GetMesh(grpc::CallbackServerContext*, const v1::GetMeshRequest*,
                                    v1::GetMeshResponse*) override;
  grpc::ServerUnaryReactor* DeleteMesh(grpc::CallbackServerContext*, const v1::DeleteMeshRequest*,
                                       v1::DeleteMeshResponse*) override;
  grpc::ServerReadReactor<v1::AddFieldsRequest>* AddFields(grpc::CallbackServerContext*,
                                                           v1::AddFieldsResponse*) override;
  grpc::ServerUnaryReactor* DeleteField(grpc::CallbackServerContext*, const v1::DeleteFieldRequest*,
                                        v1::DeleteFieldResponse*) override;
  grpc::ServerUnaryReactor* OpenSession(grpc::CallbackServerContext*, const v1::OpenSessionRequest*,
                                        v1::OpenSessionResponse*) override;
  grpc::ServerUnaryReactor* GetSession(grpc::CallbackServerContext*, const v1::GetSessionRequest*,
                                       v1::GetSessionResponse*) override;
  grpc::ServerUnaryReactor* ListSessions(grpc::CallbackServerContext*,
                                         const v1::ListSessionsRequest*,
                                         v1::ListSessionsResponse*) override;
  grpc::ServerUnaryReactor* CloseSession(grpc::CallbackServerContext*,
                                         const v1::CloseSessionRequest*,
                                         v1::CloseSessionResponse*) override;
  grpc::ServerUnaryReactor* GetSessionStats(grpc::CallbackServerContext*,
                                            const v1::GetSessionStatsRequest*,
                                            v1::GetSessionStatsResponse*) override;
  grpc::ServerUnaryReactor* GetRelation(grpc::CallbackServerContext*, const v1::GetRelationRequest*,
                                        v1::GetRelationResponse*) override;
  grpc::ServerUnaryReactor* GetRelationBatch(grpc::CallbackServerContext*,
                                             const v1::GetRelationBatchRequest*,
                                             v1::GetRelationBatchResponse*) override;
  grpc::ServerBidiReactor<v1::StreamRelationsRequest, v1::StreamRelationsResponse>* StreamRelations(
      grpc::CallbackServerContext*) override;
  grpc::ServerWriteReactor<v1::RunJobResponse>* RunJob(grpc::CallbackServerContext*,
                                                       const v1::RunJobRequest*) override;
  grpc::ServerUnaryReactor* CancelJob(grpc::CallbackServerContext*, const v1::CancelJobRequest*,
                                      v1::CancelJobResponse*) override;

  // The metrics' gauges now (Metrics reads them at each scrape).
  GaugeValues Gauges() const;

 private:
  // ReactorHost: what the reactors use (reactor_host.h).
  absl::Status Admit(grpc::CallbackServerContext* context) const override;
  void Count(std::string_view rpc, const absl::Status& status) override;
  Executor& background() override { return background_; }
  Executor& relations() override { return relations_; }
  Executor& jobs() override { return jobs_; }
  void BeforeWork(std::string_view rpc) override;
  absl::Status AnswerRelation(const std::string& session_id, v1::Relation relation,
                              const v1::Simplex& simplex, bool include_vertices,
                              std::vector<int64_t>& ids, std::vector<int64_t>* vertices,
                              const Progress& stop) override;
  absl::Status AnswerBatch(const std::string& session_id, v1::Relation relation,
                           const v1::Array* ids, const v1::Array* vertex_tuples, v1::Array* offsets,
                           v1::Array* values, std::vector<ItemFailure>* failures,
                           const Progress& stop) override;
  absl::StatusOr<std::shared_ptr<const LoadedMesh>> LoadRequested(
      const v1::LoadMeshRequest& request, const Progress& progress) override;
  MeshRegistry& meshes() override { return *meshes_; }
  MemoryBudget& budget() override { return *budget_; }
  int SessionsOnMesh(const std::string& mesh_id) override {
    return sessions_->SessionsOnMesh(mesh_id);
  }
  absl::StatusOr<std::shared_ptr<Session>> FindSession(const std::string& id) override;
  absl::StatusOr<JobLease> StartJob(const std::string& session_id, Algorithm algorithm) override;
  void RecordJob(std::string_view algorithm, std::string_view structure, double seconds,
                 const EngineStats& engine) override;

  // Answers inline, on the gRPC thread: for calls that take microseconds and wait for nothing.
  template <class Fn>
  grpc::ServerUnaryReactor* Unary(grpc::CallbackServerContext* context, std::string_view rpc,
                                  Fn&& fn);
  // Answers from `executor`: fn(const Progress&) -> absl::Status, where the progress stops when
  // the call is cancelled, its deadline passes or the server drains. fn must capture the request
  // and response pointers by value.
  template <class Fn>
  grpc::ServerUnaryReactor* Offload(Executor& executor, grpc::CallbackServerContext* context,
                                    std::string_view rpc, Fn fn);

  MeshRegistry* meshes_;
  SessionManager* sessions_;
  UploadSpool* spool_;
  MemoryBudget* budget_;
  Metrics* metrics_;
  const ServiceLimits limits_;
  const std::string token_;
  const std::function<void(std::string_view)> before_work_;
  std::atomic<bool> draining_{false};
  // Declared last: destroyed first, each cancelling its tasks and waiting for them. Loads and
  // openings run a few at once (each is itself multi-threaded), the rest wait in order.
  Executor background_;
  Executor relations_;
  Executor jobs_;
};

}  // namespace actopo::service

#endif  // ACTOPO_SERVER_SERVICE_SERVICE_H_
