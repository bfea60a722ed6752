// The server's memory budget: meshes and sessions reserve their estimated bytes before they
// allocate, so a request that would not fit gets RESOURCE_EXHAUSTED instead of an OOM kill.
#ifndef ACTOPO_SERVER_SERVICE_MEMORY_BUDGET_H_
#define ACTOPO_SERVER_SERVICE_MEMORY_BUDGET_H_

#include <cstdint>
#include <string>
#include <utility>

#include "absl/status/status.h"
#include "server/core/sync.h"

namespace actopo::service {

class MemoryBudget {
 public:
  // `name` and `advice` word the error of a reservation that does not fit.
  explicit MemoryBudget(
      int64_t limit_bytes, std::string name = "memory budget",
      std::string advice = "delete meshes or close sessions, or raise --memory-budget-mib")
      : limit_(limit_bytes), name_(std::move(name)), advice_(std::move(advice)) {}

  // Reserves `bytes` for `what` (named in the error), or fails without reserving.
  absl::Status Reserve(int64_t bytes, const std::string& what);
  void Release(int64_t bytes);
  int64_t used() const;
  int64_t limit() const { return limit_; }

 private:
  const int64_t limit_;
  const std::string name_, advice_;
  mutable Mutex mu_;
  int64_t used_ ABSL_GUARDED_BY(mu_) = 0;
};

// A reservation released on destruction.
class Reservation {
 public:
  Reservation() = default;
  // An empty reservation can be resized too, once it knows its budget.
  explicit Reservation(MemoryBudget* budget) : budget_(budget) {}
  Reservation(MemoryBudget* budget, int64_t bytes) : budget_(budget), bytes_(bytes) {}
  Reservation(Reservation&& o) noexcept : budget_(o.budget_), bytes_(o.bytes_) {
    o.budget_ = nullptr;
  }
  Reservation& operator=(Reservation&& o) noexcept {
    if (this != &o) {
      Reset();
      budget_ = o.budget_;
      bytes_ = o.bytes_;
      o.budget_ = nullptr;
    }
    return *this;
  }
  ~Reservation() { Reset(); }
  int64_t bytes() const { return budget_ ? bytes_ : 0; }
  MemoryBudget* budget() const { return budget_; }
  // Grows (reserving the difference, or failing with nothing changed) or shrinks to `bytes`.
  absl::Status Resize(int64_t bytes, const std::string& what) {
    if (budget_ == nullptr) return absl::FailedPreconditionError("reservation without a budget");
    if (bytes > bytes_) {
      if (absl::Status s = budget_->Reserve(bytes - bytes_, what); !s.ok()) return s;
    } else {
      budget_->Release(bytes_ - bytes);
    }
    bytes_ = bytes;
    return absl::OkStatus();
  }

 private:
  void Reset() {
    if (budget_) budget_->Release(bytes_);
    budget_ = nullptr;
  }
  MemoryBudget* budget_ = nullptr;
  int64_t bytes_ = 0;
};

}  // namespace actopo::service

#endif  // ACTOPO_SERVER_SERVICE_MEMORY_BUDGET_H_
