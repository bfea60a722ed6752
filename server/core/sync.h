// A mutex and a condition variable that clang's thread-safety analysis understands.
//
//   Mutex mu_;
//   int pending_ ABSL_GUARDED_BY(mu_) = 0;
//   ...
//   MutexLock lock(mu_);
//   while (pending_ == 0) ready_.Wait(mu_);
//
// libstdc++'s std::mutex carries no capability attributes, so members guarded by one cannot be
// checked; absl::Mutex can, but Debian's Abseil is not built with ThreadSanitizer, which then
// misses the happens-before edges its locks create and reports false races. These wrap
// std::mutex (seen by TSan through pthread) with Abseil's annotation macros. The annotations are
// checked by the clang build with -Wthread-safety (make test-thread-safety); GCC ignores them.
#ifndef ACTOPO_SERVER_CORE_SYNC_H_
#define ACTOPO_SERVER_CORE_SYNC_H_

#include <condition_variable>
#include <mutex>

#include "absl/base/thread_annotations.h"

namespace actopo {

class ABSL_LOCKABLE Mutex {
 public:
  Mutex() = default;
  Mutex(const Mutex&) = delete;
  Mutex& operator=(const Mutex&) = delete;

  void Lock() ABSL_EXCLUSIVE_LOCK_FUNCTION() { mu_.lock(); }
  void Unlock() ABSL_UNLOCK_FUNCTION() { mu_.unlock(); }

  // BasicLockable, for std::condition_variable_any inside CondVar only.
  void lock() ABSL_EXCLUSIVE_LOCK_FUNCTION() { mu_.lock(); }
  void unlock() ABSL_UNLOCK_FUNCTION() { mu_.unlock(); }

 private:
  std::mutex mu_;
};

// Holds `mu` for its scope.
class ABSL_SCOPED_LOCKABLE MutexLock {
 public:
  explicit MutexLock(Mutex& mu) ABSL_EXCLUSIVE_LOCK_FUNCTION(mu) : mu_(mu) { mu_.Lock(); }
  ~MutexLock() ABSL_UNLOCK_FUNCTION() { mu_.Unlock(); }
  MutexLock(const MutexLock&) = delete;
  MutexLock& operator=(const MutexLock&) = delete;

 private:
  Mutex& mu_;
};

class CondVar {
 public:
  // Releases `mu` while waiting and holds it again on return. Wakes spuriously too: wait in a
  // loop on the condition.
  void Wait(Mutex& mu) ABSL_EXCLUSIVE_LOCKS_REQUIRED(mu) { cv_.wait(mu); }
  // Wait, for at most `timeout`.
  template <class Duration>
  void WaitFor(Mutex& mu, Duration timeout) ABSL_EXCLUSIVE_LOCKS_REQUIRED(mu) {
    cv_.wait_for(mu, timeout);
  }
  void Signal() { cv_.notify_one(); }
  void SignalAll() { cv_.notify_all(); }

 private:
  std::condition_variable_any cv_;
};

}  // namespace actopo

#endif  // ACTOPO_SERVER_CORE_SYNC_H_
