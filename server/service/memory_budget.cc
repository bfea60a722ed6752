#include "server/service/memory_budget.h"

#include "absl/strings/str_cat.h"

namespace actopo::service {

absl::Status MemoryBudget::Reserve(int64_t bytes, const std::string& what) {
  MutexLock lock(mu_);
  if (used_ + bytes > limit_) {
    return absl::ResourceExhaustedError(
        absl::StrCat(what, " needs about ", bytes >> 20, " MiB but the server's memory budget has ",
                     (limit_ - used_) >> 20, " MiB left of ", limit_ >> 20,
                     " MiB (delete meshes or close sessions, or raise --memory-budget-mib)"));
  }
  used_ += bytes;
  return absl::OkStatus();
}

void MemoryBudget::Release(int64_t bytes) {
  MutexLock lock(mu_);
  used_ -= bytes;
}

int64_t MemoryBudget::used() const {
  MutexLock lock(mu_);
  return used_;
}

}  // namespace actopo::service
