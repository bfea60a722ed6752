#include "server/service/session_manager.h"

#include <utility>

#include "absl/strings/str_cat.h"
#include "server/core/process_memory.h"
#include "server/core/status_macros.h"
#include "server/service/ids.h"

namespace actopo::service {

SessionManager::SessionManager(SessionLimits limits, MemoryBudget* budget)
    : limits_(limits), budget_(budget), reaper_([this] { ReapIdle(); }) {}

SessionManager::~SessionManager() {
  {
    MutexLock lock(mu_);
    stop_ = true;
  }
  reaper_cv_.SignalAll();
  reaper_.join();
  std::map<std::string, std::shared_ptr<Session>> closing;
  {
    MutexLock lock(mu_);
    closing.swap(sessions_);
  }
}

absl::StatusOr<std::shared_ptr<Session>> SessionManager::Open(
    std::shared_ptr<const LoadedMesh> mesh, const SessionOptions& options,
    const Progress& progress) {
  RETURN_IF_ERROR(Session::Validate(options));
  {
    MutexLock lock(mu_);
    if (int(sessions_.size()) + opening_ >= limits_.max_sessions) {
      return absl::ResourceExhaustedError(
          absl::StrCat("sessions: the server holds its maximum of ", limits_.max_sessions,
                       " sessions; close one first (--max-sessions raises the limit)"));
    }
    const int query = Session::QueryThreads(options), job = Session::JobThreads(options);
    if (query + job > limits_.max_engine_threads) {
      return absl::InvalidArgumentError(absl::StrCat(
          "engine: this session needs ", query, " query producers plus ", job,
          " threads per job, more than the server's budget of ", limits_.max_engine_threads,
          " engine threads; use fewer consumers, producers or query readers"));
    }
    if (threads_ + query > limits_.max_engine_threads) {
      return absl::ResourceExhaustedError(absl::StrCat(
          "engine.producers: ", query, " more engine threads would exceed the server's ",
          "budget of ", limits_.max_engine_threads, " (", threads_, " in use)"));
    }
    threads_ += query;
    ++opening_;  // the slot is held while the session is built, outside the lock
  }
  absl::StatusOr<std::unique_ptr<Session>> session =
      Session::Open(mesh, options, budget_, progress);
  MutexLock lock(mu_);
  --opening_;
  if (!session.ok()) {
    threads_ -= Session::QueryThreads(options);
    return session.status();
  }
  // A session holds hundreds of MiB on big meshes: hand them back to the system when it goes.
  std::shared_ptr<Session> shared(session->release(), [](Session* s) {
    delete s;
    ReleaseFreeMemory();
  });
  sessions_[shared->id()] = shared;
  return shared;
}

absl::StatusOr<std::shared_ptr<Session>> SessionManager::Get(const std::string& id) const {
  MutexLock lock(mu_);
  auto it = sessions_.find(id);
  if (it == sessions_.end()) {
    return absl::NotFoundError(absl::StrCat("session_id: no session '", id,
                                            "' (closed, timed out after idling, or never opened)"));
  }
  return it->second;
}

std::vector<std::shared_ptr<Session>> SessionManager::List() const {
  MutexLock lock(mu_);
  std::vector<std::shared_ptr<Session>> out;
  for (const auto& [id, s] : sessions_) out.push_back(s);
  return out;
}

absl::Status SessionManager::Close(const std::string& id) {
  std::shared_ptr<Session> closing;
  {
    MutexLock lock(mu_);
    auto it = sessions_.find(id);
    if (it == sessions_.end()) {
      return absl::NotFoundError(absl::StrCat("session_id: no session '", id, "'"));
    }
    // Its job (if any) sees the flag and ends with CANCELLED; its lease stays valid until then.
    if (auto job = job_of_session_.find(id); job != job_of_session_.end()) {
      jobs_.at(job->second)->cancel = true;
    }
    closing = std::move(it->second);
    sessions_.erase(it);
    threads_ -= closing->query_threads();
  }
  return absl::OkStatus();  // freed when the last request or job holding it ends
}

int SessionManager::SessionsOnMesh(const std::string& mesh_id) const {
  MutexLock lock(mu_);
  int n = 0;
  for (const auto& [id, s] : sessions_) n += s->mesh().id == mesh_id;
  return n;
}

size_t SessionManager::size() const {
  MutexLock lock(mu_);
  return sessions_.size();
}

JobLease& JobLease::operator=(JobLease&& other) noexcept {
  if (this != &other) {
    Release();
    owner_ = std::exchange(other.owner_, nullptr);
    job_ = std::move(other.job_);
    threads_ = std::exchange(other.threads_, 0);
  }
  return *this;
}

void JobLease::Release() {
  if (owner_ == nullptr) return;
  std::exchange(owner_, nullptr)->EndJob(*job_, threads_);
}

absl::StatusOr<JobLease> SessionManager::StartJob(const std::string& session_id,
                                                  Algorithm algorithm) {
  MutexLock lock(mu_);
  if (draining_) return absl::UnavailableError("the server is shutting down");
  auto session = sessions_.find(session_id);
  if (session == sessions_.end()) {
    return absl::NotFoundError(absl::StrCat("session_id: no session '", session_id,
                                            "' (closed, timed out after idling, or never opened)"));
  }
  if (auto running = job_of_session_.find(session_id); running != job_of_session_.end()) {
    return absl::FailedPreconditionError(absl::StrCat("session_id: session '", session_id,
                                                      "' is running job '", running->second,
                                                      "'; wait for it or cancel it (CancelJob)"));
  }
  const int needed = session->second->job_threads();
  if (threads_ + needed > limits_.max_engine_threads) {
    return absl::ResourceExhaustedError(absl::StrCat(
        "engine: the job needs ", needed, " engine threads but the server's budget of ",
        limits_.max_engine_threads, " has ", limits_.max_engine_threads - threads_,
        " left; retry when other jobs end"));
  }
  auto job = std::make_shared<Job>();
  job->id = NewId("job");
  job->session_id = session_id;
  job->algorithm = algorithm;
  job->started = absl::Now();
  jobs_[job->id] = job;
  job_of_session_[session_id] = job->id;
  threads_ += needed;
  return JobLease(this, std::move(job), needed);
}

void SessionManager::EndJob(const Job& job, int threads) {
  MutexLock lock(mu_);
  jobs_.erase(job.id);
  job_of_session_.erase(job.session_id);
  threads_ -= threads;
}

absl::Status SessionManager::CancelJob(const std::string& job_id) {
  MutexLock lock(mu_);
  auto it = jobs_.find(job_id);
  if (it == jobs_.end()) {
    return absl::NotFoundError(
        absl::StrCat("job_id: no running job '", job_id, "' (finished or never started)"));
  }
  it->second->cancel = true;
  return absl::OkStatus();
}

std::string SessionManager::RunningJob(const std::string& session_id) const {
  MutexLock lock(mu_);
  auto it = job_of_session_.find(session_id);
  return it == job_of_session_.end() ? std::string() : it->second;
}

int SessionManager::running_jobs() const {
  MutexLock lock(mu_);
  return int(jobs_.size());
}

void SessionManager::Drain() {
  MutexLock lock(mu_);
  draining_ = true;
  for (auto& [id, job] : jobs_) job->cancel = true;
}

int SessionManager::threads_in_use() const {
  MutexLock lock(mu_);
  return threads_;
}

void SessionManager::ReapIdle() {
  mu_.Lock();
  while (!stop_) {
    reaper_cv_.WaitFor(mu_, std::chrono::seconds(1));
    const absl::Time now = absl::Now();
    std::vector<std::shared_ptr<Session>> expired;
    for (auto it = sessions_.begin(); it != sessions_.end();) {
      if (!job_of_session_.contains(it->first) &&
          now - it->second->last_used() > limits_.idle_timeout) {
        threads_ -= it->second->query_threads();
        expired.push_back(std::move(it->second));
        it = sessions_.erase(it);
      } else {
        ++it;
      }
    }
    mu_.Unlock();
    expired.clear();  // destroy outside the lock
    mu_.Lock();
  }
  mu_.Unlock();
}

}  // namespace actopo::service
