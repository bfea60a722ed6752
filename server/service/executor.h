// Slow requests (loading and partitioning a mesh, completing an upload, opening a session) run
// here, on a few threads of their own, so gRPC's threads keep answering cheap calls meanwhile.
//
//   BackgroundWork work(4);
//   auto cancel = std::make_shared<std::atomic<bool>>(false);   // set by the call's OnCancel
//   work.Run(cancel, [=] { reactor->Finish(ToGrpcStatus(LoadWatching(*cancel))); });
//   work.CancelAll();   // draining: every queued and running task sees its flag set
//
// Tasks start in the order they were given. A queued task whose flag is set still runs (it must
// finish its call) and is expected to return at once. The destructor cancels every task and
// waits for them all.
#ifndef ACTOPO_SERVER_SERVICE_BACKGROUND_H_
#define ACTOPO_SERVER_SERVICE_BACKGROUND_H_

#include <atomic>
#include <condition_variable>
#include <deque>
#include <functional>
#include <memory>
#include <mutex>
#include <thread>
#include <vector>

namespace actopo::service {

class BackgroundWork {
 public:
  using CancelFlag = std::shared_ptr<std::atomic<bool>>;

  explicit BackgroundWork(int threads);
  ~BackgroundWork();
  BackgroundWork(const BackgroundWork&) = delete;
  BackgroundWork& operator=(const BackgroundWork&) = delete;

  void Run(CancelFlag cancel, std::function<void()> task);
  // Sets the flag of every queued and running task, and of every task given from now on.
  void CancelAll();
  // Tasks queued or running.
  int pending() const;

 private:
  struct Task {
    CancelFlag cancel;
    std::function<void()> run;
  };
  void Loop();

  mutable std::mutex mu_;
  std::condition_variable wake_;
  std::deque<Task> queue_;
  std::vector<CancelFlag> running_;
  bool cancel_all_ = false;
  bool stop_ = false;
  std::vector<std::thread> threads_;
};

}  // namespace actopo::service

#endif  // ACTOPO_SERVER_SERVICE_BACKGROUND_H_
