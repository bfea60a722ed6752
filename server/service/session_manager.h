// Open sessions, their limits (count, engine threads, memory) and the idle timeout.
#ifndef ACTOPO_SERVER_SERVICE_SESSION_MANAGER_H_
#define ACTOPO_SERVER_SERVICE_SESSION_MANAGER_H_

#include <condition_variable>
#include <map>
#include <memory>
#include <mutex>
#include <thread>
#include <vector>

#include "absl/status/statusor.h"
#include "server/service/memory_budget.h"
#include "server/service/mesh_registry.h"
#include "server/service/session.h"

namespace actopo::service {

struct SessionLimits {
  int max_sessions = 64;
  int max_engine_threads = 64;   // producers of all sessions plus running jobs' threads
  absl::Duration idle_timeout = absl::Minutes(30);
};

class SessionManager {
 public:
  SessionManager(SessionLimits limits, MemoryBudget* budget);
  ~SessionManager();  // closes every session

  absl::StatusOr<std::shared_ptr<Session>> Open(std::shared_ptr<const LoadedMesh> mesh,
                                                const SessionOptions& options);
  absl::StatusOr<std::shared_ptr<Session>> Get(const std::string& id) const;
  std::vector<std::shared_ptr<Session>> List() const;
  absl::Status Close(const std::string& id);
  int SessionsOnMesh(const std::string& mesh_id) const;
  size_t size() const;

  // Job threads: reserve before a job starts, release when it ends.
  absl::Status ReserveJobThreads(const Session& session);
  void ReleaseJobThreads(const Session& session);
  int threads_in_use() const;

 private:
  void ReapIdle();

  const SessionLimits limits_;
  MemoryBudget* budget_;
  mutable std::mutex mu_;
  std::map<std::string, std::shared_ptr<Session>> sessions_;
  int threads_ = 0;
  bool stop_ = false;
  std::condition_variable reaper_cv_;
  std::thread reaper_;
};

}  // namespace actopo::service

#endif  // ACTOPO_SERVER_SERVICE_SESSION_MANAGER_H_
