// Readers for a session's relation queries: up to `capacity` calls read at once, each with a
// reader of its own (readers are not thread-safe; the structures behind them are shared). A
// call finding every reader busy waits for one; that wait is the query's queue time.
//
//   ReaderPool<CompactStructure::Reader> pool(4, [&] { return structure.NewReader(); });
//   auto reader = pool.Acquire();     // blocks while 4 are in use
//   reader->vertex_star(v);           // returned to the pool when `reader` goes out of scope
#ifndef ACTOPO_SERVER_SERVICE_READER_POOL_H_
#define ACTOPO_SERVER_SERVICE_READER_POOL_H_

#include <functional>
#include <memory>
#include <utility>
#include <vector>

#include "server/core/sync.h"

namespace actopo::service {

template <class Reader>
class ReaderPool {
 public:
  // `make` builds a reader (called under the pool's lock, at most `capacity` times).
  ReaderPool(int capacity, std::function<Reader()> make)
      : capacity_(capacity), make_(std::move(make)) {}
  ReaderPool(const ReaderPool&) = delete;
  ReaderPool& operator=(const ReaderPool&) = delete;

  class Lease {
   public:
    Lease(Lease&& other) noexcept
        : pool_(std::exchange(other.pool_, nullptr)), reader_(std::move(other.reader_)) {}
    Lease& operator=(Lease&&) = delete;
    ~Lease() {
      if (pool_ != nullptr) pool_->Return(std::move(reader_));
    }
    Reader& operator*() const { return *reader_; }
    Reader* operator->() const { return reader_.get(); }

   private:
    friend class ReaderPool;
    Lease(ReaderPool* pool, std::unique_ptr<Reader> reader)
        : pool_(pool), reader_(std::move(reader)) {}
    ReaderPool* pool_;
    std::unique_ptr<Reader> reader_;
  };

  Lease Acquire() {
    MutexLock lock(mu_);
    while (free_.empty() && created_ >= capacity_) available_.Wait(mu_);
    if (free_.empty()) {
      ++created_;
      return Lease(this, std::make_unique<Reader>(make_()));
    }
    std::unique_ptr<Reader> reader = std::move(free_.back());
    free_.pop_back();
    return Lease(this, std::move(reader));
  }

  int capacity() const { return capacity_; }

  // Destroys the idle readers; every lease must have been returned.
  void Clear() {
    MutexLock lock(mu_);
    free_.clear();
    created_ = 0;
  }

 private:
  void Return(std::unique_ptr<Reader> reader) {
    {
      MutexLock lock(mu_);
      free_.push_back(std::move(reader));
    }
    available_.Signal();
  }

  const int capacity_;
  const std::function<Reader()> make_;
  Mutex mu_;
  CondVar available_;
  std::vector<std::unique_ptr<Reader>> free_ ABSL_GUARDED_BY(mu_);
  int created_ ABSL_GUARDED_BY(mu_) = 0;
};

}  // namespace actopo::service

#endif  // ACTOPO_SERVER_SERVICE_READER_POOL_H_
