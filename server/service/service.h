// The actopo.v1.TopologyService implementation (gRPC callback API): one reactor per streaming
// RPC; cheap unary RPCs answered inline (service_unary.cc); loading, uploading and opening
// sessions in the background work, cancellable (service_meshes.cc); relation and job streams in
// service_streams.cc.
#ifndef ACTOPO_SERVER_SERVICE_SERVICE_H_
#define ACTOPO_SERVER_SERVICE_SERVICE_H_

#include <atomic>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "actopo/v1/topology_service.grpc.pb.h"
#include "server/core/progress.h"
#include "server/service/background.h"
#include "server/service/memory_budget.h"
#include "server/service/mesh_registry.h"
#include "server/service/metrics.h"
#include "server/service/session_manager.h"

namespace actopo::service {

struct ServiceLimits {
  int max_batch_size = 1 << 20;
  int64_t max_message_bytes = 64 << 20;
  // Reported by GetServerInfo (enforced by the registry and the session manager).
  int max_meshes = 0;
  int max_sessions = 0;
  int max_engine_threads = 0;
  int64_t session_idle_timeout_seconds = 0;
};

namespace v1 = ::actopo::v1;

class TopologyServiceImpl final : public v1::TopologyService::CallbackService {
 public:
  TopologyServiceImpl(MeshRegistry* meshes, SessionManager* sessions, MemoryBudget* budget,
                      Metrics* metrics, ServiceLimits limits, std::string token);

  // Stop accepting work (UNAVAILABLE) and cancel running jobs; health is set by the server.
  void Drain();
  bool draining() const { return draining_.load(); }

  grpc::ServerUnaryReactor* GetServerInfo(grpc::CallbackServerContext*,
                                          const v1::GetServerInfoRequest*,
                                          v1::GetServerInfoResponse*) override;
  grpc::ServerUnaryReactor* LoadMesh(grpc::CallbackServerContext*, const v1::LoadMeshRequest*,
                                     v1::LoadMeshResponse*) override;
  grpc::ServerWriteReactor<v1::LoadMeshWithProgressResponse>* LoadMeshWithProgress(
      grpc::CallbackServerContext*, const v1::LoadMeshWithProgressRequest*) override;
  grpc::ServerReadReactor<v1::UploadMeshRequest>* UploadMesh(grpc::CallbackServerContext*,
                                                             v1::UploadMeshResponse*) override;
  grpc::ServerUnaryReactor* ListMeshes(grpc::CallbackServerContext*, const v1::ListMeshesRequest*,
                                       v1::ListMeshesResponse*) override;
  grpc::ServerUnaryReactor* GetMesh(grpc::CallbackServerContext*, const v1::GetMeshRequest*,
                                    v1::GetMeshResponse*) override;
  grpc::ServerUnaryReactor* DeleteMesh(grpc::CallbackServerContext*, const v1::DeleteMeshRequest*,
                                       v1::DeleteMeshResponse*) override;
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

  // Used by the reactors (service_streams.cc).
  absl::Status Admit(grpc::CallbackServerContext* context) const;
  void Count(std::string_view rpc, const absl::Status& status);
  absl::Status AnswerRelation(const std::string& session_id, v1::Relation relation,
                              const v1::Simplex& simplex, bool include_vertices,
                              std::vector<int64_t>& ids, std::vector<int64_t>* vertices);
  // A batch by ids or vertex_tuples (exactly one non-null) answered as CSR arrays. With
  // `failures`, an item that fails gets an empty row and an entry there; without, the first
  // failure fails the call.
  struct ItemFailure {
    int64_t index;
    absl::Status status;
  };
  absl::Status AnswerBatch(const std::string& session_id, v1::Relation relation,
                           const v1::Array* ids, const v1::Array* vertex_tuples, v1::Array* offsets,
                           v1::Array* values, std::vector<ItemFailure>* failures);
  // The mesh a LoadMesh request names, loaded, partitioned and registered.
  absl::StatusOr<std::shared_ptr<const LoadedMesh>> LoadRequested(
      const v1::LoadMeshRequest& request, const Progress& progress);
  BackgroundWork& background() { return background_; }
  MeshRegistry& meshes() { return *meshes_; }
  MemoryBudget& budget() { return *budget_; }
  SessionManager& sessions() { return *sessions_; }
  Metrics& metrics() { return *metrics_; }
  const ServiceLimits& limits() const { return limits_; }
  // The metrics' gauges now (Metrics reads them at each scrape).
  GaugeValues Gauges() const;

 private:
  // Answers inline, on the gRPC thread: for calls that take microseconds.
  template <class Fn>
  grpc::ServerUnaryReactor* Unary(grpc::CallbackServerContext* context, std::string_view rpc,
                                  Fn&& fn);
  // Answers from the background work: fn(const Progress&) -> absl::Status, where the progress
  // stops when the call is cancelled, its deadline passes or the server drains. fn must capture
  // the request and response pointers by value.
  template <class Fn>
  grpc::ServerUnaryReactor* Background(grpc::CallbackServerContext* context, std::string_view rpc,
                                       Fn fn);

  MeshRegistry* meshes_;
  SessionManager* sessions_;
  MemoryBudget* budget_;
  Metrics* metrics_;
  const ServiceLimits limits_;
  const std::string token_;
  std::atomic<bool> draining_{false};
  // Loads, uploads and session openings; a few run at once (each is itself multi-threaded),
  // the rest wait in order. Declared last: destroyed first, waiting for its tasks.
  BackgroundWork background_;
};

// A call's deadline on the steady clock (time_point::max() when it has none).
Progress::Clock::time_point SteadyDeadline(const grpc::CallbackServerContext& context);

}  // namespace actopo::service

#endif  // ACTOPO_SERVER_SERVICE_SERVICE_H_
