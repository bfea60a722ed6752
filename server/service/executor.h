// The service's threads: every piece of work a call hands over runs on an Executor the service
// owns, so gRPC's threads only start and finish calls. The service has three (service.h):
// loads and session openings, relation answers, and jobs, each bounded by its thread count.
//
//   Executor relations("relations", 4);
//   auto cancel = std::make_shared<std::atomic<bool>>(false);   // set by the call's OnCancel
//   relations.Run(cancel, [=] { reactor->Answer(); });
//   relations.CancelAll();   // draining: every queued and running task sees its flag set
//
// Tasks start in the order they were given, on at most `threads` threads (all started at
// construction). A queued task whose flag is set still runs (it must finish its call) and is
// expected to return at once. The destructor cancels every task and waits for them all.
#ifndef ACTOPO_SERVER_SERVICE_EXECUTOR_H_
#define ACTOPO_SERVER_SERVICE_EXECUTOR_H_

#include <atomic>
#include <deque>
#include <functional>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "server/core/sync.h"

namespace actopo::service {

class Executor {
 public:
  using CancelFlag = std::shared_ptr<std::atomic<bool>>;

  // `name` names the threads (seen in traces, `top -H` and debuggers; at most 15 characters).
  Executor(std::string name, int threads);
  ~Executor();
  Executor(const Executor&) = delete;
  Executor& operator=(const Executor&) = delete;

  void Run(CancelFlag cancel, std::function<void()> task);
  // Sets the flag of every queued and running task, and of every task given from now on.
  void CancelAll();
  // Tasks queued or running.
  int pending() const;
  int threads() const { return int(threads_.size()); }

 private:
  struct Task {
    CancelFlag cancel;
    std::function<void()> run;
  };
  void Loop();

  const std::string name_;
  mutable Mutex mu_;
  CondVar wake_;
  std::deque<Task> queue_ ABSL_GUARDED_BY(mu_);
  std::vector<CancelFlag> running_ ABSL_GUARDED_BY(mu_);
  bool cancel_all_ ABSL_GUARDED_BY(mu_) = false;
  bool stop_ ABSL_GUARDED_BY(mu_) = false;
  std::vector<std::thread> threads_;  // set in the constructor, joined in the destructor
};

}  // namespace actopo::service

#endif  // ACTOPO_SERVER_SERVICE_EXECUTOR_H_
