#include "server/service/executor.h"

#include <pthread.h>

#include <algorithm>

namespace actopo::service {

Executor::Executor(std::string name, int threads) : name_(std::move(name)) {
  threads_.reserve(std::max(threads, 1));
  for (int i = 0; i < std::max(threads, 1); ++i) {
    threads_.emplace_back([this] { Loop(); });
    // Linux limits thread names to 15 characters.
    pthread_setname_np(threads_.back().native_handle(), name_.substr(0, 15).c_str());
  }
}

Executor::~Executor() {
  CancelAll();
  {
    MutexLock lock(mu_);
    stop_ = true;
  }
  wake_.SignalAll();
  for (std::thread& t : threads_) t.join();
}

void Executor::Run(CancelFlag cancel, std::function<void()> task) {
  {
    MutexLock lock(mu_);
    if (cancel_all_) cancel->store(true);
    queue_.push_back({std::move(cancel), std::move(task)});
  }
  wake_.Signal();
}

void Executor::CancelAll() {
  MutexLock lock(mu_);
  cancel_all_ = true;
  for (const Task& t : queue_) t.cancel->store(true);
  for (const CancelFlag& c : running_) c->store(true);
}

int Executor::pending() const {
  MutexLock lock(mu_);
  return int(queue_.size() + running_.size());
}

void Executor::Loop() {
  mu_.Lock();
  while (true) {
    // Queued tasks run even when stopping: each must finish its call.
    while (!stop_ && queue_.empty()) wake_.Wait(mu_);
    if (queue_.empty()) break;
    Task task = std::move(queue_.front());
    queue_.pop_front();
    running_.push_back(task.cancel);
    mu_.Unlock();
    task.run();
    task.run = nullptr;  // what the task captured goes before it counts as done
    mu_.Lock();
    running_.erase(std::find(running_.begin(), running_.end(), task.cancel));
  }
  mu_.Unlock();
}

}  // namespace actopo::service
