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
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "absl/time/time.h"
#include "server/algorithms/structure_options.h"
#include "server/core/actopo_structure.h"
#include "server/core/compact_structure.h"
#include "server/core/explicit_structure.h"
#include "server/core/sync.h"
#include "server/results/result_files.h"
#include "server/results/run_algorithm.h"
#include "server/service/memory_budget.h"
#include "server/service/mesh_registry.h"
#include "server/service/reader_pool.h"

namespace actopo::service {

struct SessionOptions {
  std::string scalar_field;    // empty: the first floating-point field
  StructureOptions structure;  // with WithDefaults applied; validated as the request's engine.*
};

// The request field a simplex came from, for error messages: "ids[12]" for item 12 of a batch
// (formatted only when an error is reported).
struct FieldRef {
  FieldRef(const char* name, int64_t index = -1) : name(name), index(index) {}  // NOLINT
  std::string_view name;
  int64_t index;
  std::string ToString() const;
};

// What a finished job hands back.
struct JobOutcome {
  AlgorithmOutcome outcome;
  double faces_s = 0;  // building (or waiting for) the mesh's faces, before the run
  EngineStats engine;  // of this job
  MemoryStats memory;
};

// Cumulative statistics of a session.
struct SessionStats {
  EngineStats engine;
  MemoryStats memory;
  int64_t queries = 0, query_ns = 0;  // calls, and their time from arrival to answer
  // Where query time went: waiting for a free reader, resolving and computing the rows, packing
  // the answers into messages (the service's part); over `simplices` answered rows.
  int64_t query_simplices = 0, query_queue_ns = 0, query_compute_ns = 0, query_serialize_ns = 0;
  int64_t jobs = 0, job_ns = 0;
  double preprocess_seconds = 0;
};

class Session {
 public:
  // Ranges of the engine options; errors name the option and value.
  static absl::Status Validate(const SessionOptions& options);
  // Preprocessing (the vertex order, an explicit structure's relations) reports phase
  // "precompute" to `progress` and stops when it says so.
  static absl::StatusOr<std::unique_ptr<Session>> Open(std::shared_ptr<const LoadedMesh> mesh,
                                                       const SessionOptions& options,
                                                       MemoryBudget* budget,
                                                       const Progress& progress = {});
  ~Session();

  const std::string& id() const { return id_; }
  const LoadedMesh& mesh() const { return *mesh_; }
  const std::shared_ptr<const LoadedMesh>& shared_mesh() const { return mesh_; }
  const SessionOptions& options() const { return options_; }
  const std::string& scalar_name() const { return scalar_name_; }
  absl::Time created() const { return created_; }
  absl::Time last_used() const;
  void Touch();
  // Engine threads a session holds while open (its query engine's producers) and needs per job.
  static int QueryThreads(const SessionOptions& options);
  static int JobThreads(const SessionOptions& options);
  int query_threads() const { return QueryThreads(options_); }
  int job_threads() const { return JobThreads(options_); }
  static int64_t EstimateBytes(const LoadedMesh& mesh, const SessionOptions& options);

  // Simplex ids on the wire: input ids for vertices and tetrahedra, service (internal) ids for
  // edges and triangles. Errors name the field and value.
  absl::StatusOr<SimplexId> ResolveId(int dimension, int64_t id, FieldRef field) const;
  absl::StatusOr<SimplexId> ResolveVertices(int dimension, std::span<const int64_t> vertices,
                                            FieldRef field) const;

  // Relation r of each simplex (internal ids) as CSR rows: appends the row in wire ids to
  // `values` and its end to `offsets`; with `vertices`, also the input vertices of each result
  // edge or triangle. Thread-safe: up to options().query_readers calls read at once (explicit:
  // any number), the others wait for a reader. One reader serves the whole batch.
  void Query(Relation r, std::span<const SimplexId> simplices, std::vector<int64_t>& offsets,
             std::vector<int64_t>& values, std::vector<int64_t>* vertices = nullptr);
  // One simplex: its row appended to `ids`.
  void Query(Relation r, SimplexId s, std::vector<int64_t>& ids,
             std::vector<int64_t>* vertices = nullptr);
  // Time the service spent packing query answers (reported in the stats' breakdown).
  void AddQuerySerializeTime(int64_t ns) {
    query_serialize_ns_.fetch_add(ns, std::memory_order_relaxed);
  }

  // Runs an algorithm. The caller holds the session's JobLease (SessionManager::StartJob).
  // What comes before the run reports to `prepare` (phase "faces": the mesh's edges and
  // triangles, built or waited for when the algorithm reads them); the run to context.progress.
  // `whole_job` false: one field of a job over several, which counts once, when it has
  // finished every field (CountJob).
  absl::StatusOr<JobOutcome> RunJob(const AlgorithmInput& input, const RunContext& context,
                                    const Progress::Report& prepare = {}, bool whole_job = true);
  // A finished job in the session's statistics.
  void CountJob(int64_t ns);
  const AlgorithmInput& base_input() const { return base_; }
  // For result arrays and files.
  const ResultContext& result_context();

  SessionStats stats() const;

 private:
  Session() = default;
  template <class Reader>
  void AppendRows(Reader& reader, Relation r, std::span<const SimplexId> simplices,
                  std::vector<int64_t>& offsets, std::vector<int64_t>& values,
                  std::vector<int64_t>* vertices) const;
  // The same rows, computed in block order (internal ids) and put back in the caller's order:
  // a computing structure then builds each block's relation once per batch, whatever the
  // order of the input ids (which rarely follows the blocks). With `vertices` (single
  // simplices), in the given order.
  template <class Reader>
  void AppendRowsInBlockOrder(Reader& reader, Relation r, std::span<const SimplexId> simplices,
                              std::vector<int64_t>& offsets, std::vector<int64_t>& values,
                              std::vector<int64_t>* vertices) const;

  std::string id_;
  std::shared_ptr<const LoadedMesh> mesh_;
  SessionOptions options_;
  FieldSet::Ref scalar_;  // held: deleting the field from the mesh leaves the session its copy
  std::string scalar_name_;
  absl::Time created_;
  Reservation reservation_;

  std::unique_ptr<ExplicitStructure> explicit_;
  std::unique_ptr<CompactStructure> compact_;
  // Relation queries: compact readers over a structure of their own (its cache split among
  // them), or the consumers of a query engine. Declared after what they read: destroyed first.
  std::unique_ptr<CompactStructure> query_compact_;
  std::unique_ptr<ActopoStructure> query_engine_;
  std::unique_ptr<ReaderPool<CompactStructure::Reader>> compact_readers_;
  std::unique_ptr<ReaderPool<ActopoStructure::Reader>> actopo_readers_;

  AlgorithmInput base_;  // vertex order and input tetrahedra, computed once
  Mutex result_mu_;
  std::optional<ResultContext> result_context_ ABSL_GUARDED_BY(result_mu_);

  mutable Mutex stats_mu_;
  EngineStats finished_jobs_ ABSL_GUARDED_BY(stats_mu_);
  AccessStats compact_queries_ ABSL_GUARDED_BY(stats_mu_);  // the compact query readers'
  int64_t relation_peak_bytes_ ABSL_GUARDED_BY(stats_mu_) = 0;
  std::atomic<int64_t> last_used_ns_{0};
  std::atomic<int64_t> queries_{0}, query_ns_{0}, jobs_{0}, job_ns_{0};
  std::atomic<int64_t> query_simplices_{0}, query_queue_ns_{0}, query_compute_ns_{0},
      query_serialize_ns_{0};
  double preprocess_seconds_ = 0;
};

}  // namespace actopo::service

#endif  // ACTOPO_SERVER_SERVICE_SESSION_H_
