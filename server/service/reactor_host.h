// What the service's reactors (service_meshes.cc, service_streams.cc) may use of the service,
// and nothing more: admission and counting of calls, the executors they hand work to, and the
// few operations their work needs. TopologyServiceImpl implements it privately; its own members
// stay private.
//
// The threading rule (docs/DESIGN.md, "Threads"): a reaction on a gRPC thread only starts or
// finishes operations and hands work over; anything that computes, or may wait for a reader or
// for a lock held while computing, runs on one of these executors.
#ifndef ACTOPO_SERVER_SERVICE_REACTOR_HOST_H_
#define ACTOPO_SERVER_SERVICE_REACTOR_HOST_H_

#include <grpcpp/grpcpp.h>

#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "actopo/v1/topology_service.pb.h"
#include "server/core/progress.h"
#include "server/service/executor.h"
#include "server/service/memory_budget.h"
#include "server/service/mesh_registry.h"
#include "server/service/session_manager.h"

namespace actopo::service {

namespace v1 = ::actopo::v1;

class ReactorHost {
 public:
  // UNAVAILABLE while draining, UNAUTHENTICATED without the right bearer token.
  virtual absl::Status Admit(grpc::CallbackServerContext* context) const = 0;
  // Counts a finished call (the metrics' requests by RPC and code).
  virtual void Count(std::string_view rpc, const absl::Status& status) = 0;
  virtual bool draining() const = 0;

  // The executors: loads, uploads and session openings; relation answers; algorithm runs.
  virtual Executor& background() = 0;
  virtual Executor& relations() = 0;
  virtual Executor& jobs() = 0;
  // Runs ServerOptions::before_work (tests only) on the executor's thread, before the work of
  // the call named by `rpc` (a load, upload, opening, job or offloaded relation call) begins, and
  // as each phase of a LoadMeshWithProgress begins ("LoadMeshWithProgress/PHASE").
  virtual void BeforeWork(std::string_view rpc) = 0;

  // Relations: one simplex; a batch by ids or vertex_tuples (exactly one non-null) as CSR
  // arrays. With `failures`, an item that fails gets an empty row and an entry there; without,
  // the first failure fails the call. The first call on a mesh that reads edges or triangles
  // builds them (LoadedMesh::EnsureFaces), or waits for their build, until `stop` says so.
  virtual absl::Status AnswerRelation(const std::string& session_id, v1::Relation relation,
                                      const v1::Simplex& simplex, bool include_vertices,
                                      std::vector<int64_t>& ids, std::vector<int64_t>* vertices,
                                      const Progress& stop) = 0;
  struct ItemFailure {
    int64_t index;
    absl::Status status;
  };
  virtual absl::Status AnswerBatch(const std::string& session_id, v1::Relation relation,
                                   const v1::Array* ids, const v1::Array* vertex_tuples,
                                   v1::Array* offsets, v1::Array* values,
                                   std::vector<ItemFailure>* failures, const Progress& stop) = 0;

  // Meshes: the mesh a LoadMesh request names, loaded, partitioned and registered; the registry
  // and the memory budget, for uploads.
  virtual absl::StatusOr<std::shared_ptr<const LoadedMesh>> LoadRequested(
      const v1::LoadMeshRequest& request, const Progress& progress) = 0;
  virtual MeshRegistry& meshes() = 0;
  virtual MemoryBudget& budget() = 0;
  virtual int SessionsOnMesh(const std::string& mesh_id) = 0;

  // Jobs: the session, its job lease (at most one job per session) and the job's metrics.
  virtual absl::StatusOr<std::shared_ptr<Session>> FindSession(const std::string& id) = 0;
  virtual absl::StatusOr<JobLease> StartJob(const std::string& session_id, Algorithm algorithm) = 0;
  virtual void RecordJob(std::string_view algorithm, std::string_view structure, double seconds,
                         const EngineStats& engine) = 0;

 protected:
  ~ReactorHost() = default;
};

// A call's deadline on the steady clock (time_point::max() when it has none).
Progress::Clock::time_point SteadyDeadline(const grpc::CallbackServerContext& context);

}  // namespace actopo::service

#endif  // ACTOPO_SERVER_SERVICE_REACTOR_HOST_H_
