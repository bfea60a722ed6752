// Open sessions, their jobs, their limits (count, engine threads, memory) and the idle timeout.
//
// The manager is the one owner of a job's life. A job is a lease on its session, taken
// atomically (at most one per session: a second StartJob fails with FAILED_PRECONDITION naming
// the running job) and released when the lease is destroyed, whatever ended the job: completion,
// an error, CancelJob, the client going away, the session closing or the server draining (those
// last four set the job's cancel flag; the job's thread sees it and returns).
//
//   ASSIGN_OR_RETURN(JobLease lease, sessions.StartJob(session_id, Algorithm::kMorseSmale));
//   context.cancel = &lease.job().cancel;
//   ... run ...
//   lease.Release();  // or let it go out of scope
//
// Locks: mu_ guards the sessions, the jobs and the thread count; nothing is called with it held
// except Session::query_threads() / job_threads() (constant) and destruction is done outside it.
#ifndef ACTOPO_SERVER_SERVICE_SESSION_MANAGER_H_
#define ACTOPO_SERVER_SERVICE_SESSION_MANAGER_H_

#include <atomic>
#include <map>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "absl/status/statusor.h"
#include "absl/time/time.h"
#include "server/core/sync.h"
#include "server/service/memory_budget.h"
#include "server/service/mesh_registry.h"
#include "server/service/session.h"

namespace actopo::service {

struct SessionLimits {
  int max_sessions = 64;
  int max_engine_threads = 64;  // producers of all sessions plus running jobs' threads
  absl::Duration idle_timeout = absl::Minutes(30);
};

// A running job. Only `cancel` changes after StartJob.
struct Job {
  std::string id;
  std::string session_id;
  Algorithm algorithm;
  absl::Time started;
  std::atomic<bool> cancel{false};
};

class SessionManager;

// The right to run a job on a session; move-only. Destroying it (or Release) ends the job: its
// session may run another, its engine threads return to the budget and CancelJob no longer
// finds it.
class JobLease {
 public:
  JobLease() = default;
  JobLease(JobLease&& other) noexcept { *this = std::move(other); }
  JobLease& operator=(JobLease&& other) noexcept;
  ~JobLease() { Release(); }

  Job& job() const { return *job_; }
  // For callers that must reach the cancel flag after the lease is gone (e.g. a gRPC OnCancel
  // racing with the job's end).
  const std::shared_ptr<Job>& shared_job() const { return job_; }
  void Release();

 private:
  friend class SessionManager;
  JobLease(SessionManager* owner, std::shared_ptr<Job> job, int threads)
      : owner_(owner), job_(std::move(job)), threads_(threads) {}

  SessionManager* owner_ = nullptr;
  std::shared_ptr<Job> job_;
  int threads_ = 0;
};

class SessionManager {
 public:
  SessionManager(SessionLimits limits, MemoryBudget* budget);
  ~SessionManager();  // closes every session; jobs' leases must be gone

  absl::StatusOr<std::shared_ptr<Session>> Open(std::shared_ptr<const LoadedMesh> mesh,
                                                const SessionOptions& options,
                                                const Progress& progress = {});
  absl::StatusOr<std::shared_ptr<Session>> Get(const std::string& id) const;
  std::vector<std::shared_ptr<Session>> List() const;
  // Cancels the session's running job (if any) and forgets the session; it is freed when the
  // last request or job holding it ends.
  absl::Status Close(const std::string& id);
  int SessionsOnMesh(const std::string& mesh_id) const;
  size_t size() const;

  // Starts a job on the session: NOT_FOUND (no such session), FAILED_PRECONDITION (it runs a
  // job, named in the message), RESOURCE_EXHAUSTED (engine threads), UNAVAILABLE (draining).
  absl::StatusOr<JobLease> StartJob(const std::string& session_id, Algorithm algorithm);
  // Sets the job's cancel flag; NOT_FOUND if no such job is running.
  absl::Status CancelJob(const std::string& job_id);
  // Id of the job running on the session, or "".
  std::string RunningJob(const std::string& session_id) const;
  int running_jobs() const;
  // Cancels every running job and refuses new ones (server shutdown).
  void Drain();
  int threads_in_use() const;

 private:
  friend class JobLease;
  void EndJob(const Job& job, int threads);
  void ReapIdle();

  const SessionLimits limits_;
  MemoryBudget* budget_;
  mutable Mutex mu_;
  std::map<std::string, std::shared_ptr<Session>> sessions_ ABSL_GUARDED_BY(mu_);
  std::map<std::string, std::shared_ptr<Job>> jobs_ ABSL_GUARDED_BY(mu_);  // by job id
  // session id -> job id
  std::map<std::string, std::string> job_of_session_ ABSL_GUARDED_BY(mu_);
  int threads_ ABSL_GUARDED_BY(mu_) = 0;
  int opening_ ABSL_GUARDED_BY(mu_) = 0;  // sessions being opened: each holds a max_sessions slot
  bool draining_ ABSL_GUARDED_BY(mu_) = false;
  bool stop_ ABSL_GUARDED_BY(mu_) = false;
  CondVar reaper_cv_;
  std::thread reaper_;
};

}  // namespace actopo::service

#endif  // ACTOPO_SERVER_SERVICE_SESSION_MANAGER_H_
