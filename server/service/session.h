// A session: one structure (explicit, compact or actopo) on a shared mesh and a scalar field,
// answering relation queries and running algorithm jobs (one at a time: the SessionManager's
// JobLease is what makes them exclusive).
//
//   ASSIGN_OR_RETURN(auto session, Session::Open(mesh, options, &budget));
//   ASSIGN_OR_RETURN(SimplexId v, session->ResolveId(0, 17));
//   RETURN_IF_ERROR(session->Query(Relation::kVT, v, false, ids, nullptr));
//
// Relation queries use a reader of their own: for actopo a one-consumer engine that lives with
// the session; jobs get a fresh engine configured for their algorithm (its declared relations
// and `auto` modes), whose statistics are added to the session's when the job ends.
#ifndef ACTOPO_SERVER_SERVICE_SESSION_H_
#define ACTOPO_SERVER_SERVICE_SESSION_H_

#include <atomic>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "absl/time/time.h"
#include "server/core/actopo_structure.h"
#include "server/core/compact_structure.h"
#include "server/core/explicit_structure.h"
#include "server/results/result_files.h"
#include "server/results/run_algorithm.h"
#include "server/service/memory_budget.h"
#include "server/service/mesh_registry.h"

namespace actopo::service {

enum class StructureKind : uint8_t { kExplicit, kCompact, kActopo };
std::string_view StructureName(StructureKind s);

struct SessionOptions {
  std::string scalar_field;  // empty: the first floating-point field
  StructureKind structure = StructureKind::kActopo;
  int consumers = 1;
  int producers = 2;
  double buffer_ratio = 0.2;
  std::optional<Prefetch> prefetch;      // unset: per algorithm
  std::optional<Precompute> precompute;  // unset: per algorithm
};

// What a finished job hands back.
struct JobOutcome {
  AlgorithmOutcome outcome;
  EngineStats engine;  // of this job
  MemoryStats memory;
};

// Cumulative statistics of a session.
struct SessionStats {
  EngineStats engine;
  MemoryStats memory;
  int64_t queries = 0, query_ns = 0;
  int64_t jobs = 0, job_ns = 0;
  double preprocess_seconds = 0;
};

class Session {
 public:
  // Ranges of the engine options; errors name the option and value.
  static absl::Status Validate(const SessionOptions& options);
  static absl::StatusOr<std::unique_ptr<Session>> Open(std::shared_ptr<const LoadedMesh> mesh,
                                                       const SessionOptions& options,
                                                       MemoryBudget* budget);
  ~Session();

  const std::string& id() const { return id_; }
  const LoadedMesh& mesh() const { return *mesh_; }
  const std::shared_ptr<const LoadedMesh>& shared_mesh() const { return mesh_; }
  const SessionOptions& options() const { return options_; }
  const std::string& scalar_name() const { return scalar_name_; }
  absl::Time created() const { return created_; }
  absl::Time last_used() const;
  void Touch();
  // Engine threads this session holds now and needs per job.
  int query_threads() const;
  int job_threads() const;
  static int64_t EstimateBytes(const LoadedMesh& mesh, const SessionOptions& options);

  // Simplex ids on the wire: input ids for vertices and tetrahedra, service (internal) ids for
  // edges and triangles. Errors name the field and value.
  absl::StatusOr<SimplexId> ResolveId(int dimension, int64_t id, std::string_view field) const;
  absl::StatusOr<SimplexId> ResolveVertices(int dimension, std::span<const int64_t> vertices,
                                            std::string_view field);

  // Appends relation r of internal simplex s to `ids` in wire ids; with `vertices`, also the
  // input vertices of each result edge or triangle. Thread-safe.
  absl::Status Query(Relation r, SimplexId s, std::vector<int64_t>& ids,
                     std::vector<int64_t>* vertices);

  // Runs an algorithm. The caller holds the session's JobLease (SessionManager::StartJob).
  absl::StatusOr<JobOutcome> RunJob(const AlgorithmInput& input, const RunContext& context);
  const AlgorithmInput& base_input() const { return base_; }
  // For result arrays and files.
  const ResultContext& result_context();

  SessionStats stats() const;

 private:
  Session() = default;
  template <class Reader>
  absl::Status QueryWith(Reader& reader, Relation r, SimplexId s, std::vector<int64_t>& ids,
                         std::vector<int64_t>* vertices);
  ActopoStructure::Options EngineOptions(Algorithm algorithm, int consumers) const;

  std::string id_;
  std::shared_ptr<const LoadedMesh> mesh_;
  SessionOptions options_;
  std::string scalar_name_;
  absl::Time created_;
  Reservation reservation_;

  std::unique_ptr<ExplicitStructure> explicit_;
  std::unique_ptr<CompactStructure> compact_;
  std::unique_ptr<ActopoStructure> query_engine_;
  std::optional<CompactStructure::Reader> compact_reader_;
  std::optional<ActopoStructure::Reader> actopo_reader_;
  std::mutex query_mu_;  // the compact / actopo query reader

  AlgorithmInput base_;  // vertex order and input tetrahedra, computed once
  std::mutex result_mu_;
  std::optional<ResultContext> result_context_;

  mutable std::mutex stats_mu_;
  EngineStats finished_jobs_;
  int64_t relation_peak_bytes_ = 0;
  std::atomic<int64_t> last_used_ns_{0};
  std::atomic<int64_t> queries_{0}, query_ns_{0}, jobs_{0}, job_ns_{0};
  double preprocess_seconds_ = 0;
};

}  // namespace actopo::service

#endif  // ACTOPO_SERVER_SERVICE_SESSION_H_
