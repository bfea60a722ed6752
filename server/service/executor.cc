#include "server/service/background.h"

#include <algorithm>

namespace actopo::service {

BackgroundWork::BackgroundWork(int threads) {
  threads_.reserve(std::max(threads, 1));
  for (int i = 0; i < std::max(threads, 1); ++i) threads_.emplace_back([this] { Loop(); });
}

BackgroundWork::~BackgroundWork() {
  CancelAll();
  {
    std::lock_guard<std::mutex> lock(mu_);
    stop_ = true;
  }
  wake_.notify_all();
  for (std::thread& t : threads_) t.join();
}

void BackgroundWork::Run(CancelFlag cancel, std::function<void()> task) {
  {
    std::lock_guard<std::mutex> lock(mu_);
    if (cancel_all_) cancel->store(true);
    queue_.push_back({std::move(cancel), std::move(task)});
  }
  wake_.notify_one();
}

void BackgroundWork::CancelAll() {
  std::lock_guard<std::mutex> lock(mu_);
  cancel_all_ = true;
  for (const Task& t : queue_) t.cancel->store(true);
  for (const CancelFlag& c : running_) c->store(true);
}

int BackgroundWork::pending() const {
  std::lock_guard<std::mutex> lock(mu_);
  return int(queue_.size() + running_.size());
}

void BackgroundWork::Loop() {
  std::unique_lock<std::mutex> lock(mu_);
  while (true) {
    // Queued tasks run even when stopping: each must finish its call.
    wake_.wait(lock, [this] { return stop_ || !queue_.empty(); });
    if (queue_.empty()) return;
    Task task = std::move(queue_.front());
    queue_.pop_front();
    running_.push_back(task.cancel);
    lock.unlock();
    task.run();
    task.run = nullptr;  // what the task captured goes before it counts as done
    lock.lock();
    running_.erase(std::find(running_.begin(), running_.end(), task.cancel));
  }
}

}  // namespace actopo::service
