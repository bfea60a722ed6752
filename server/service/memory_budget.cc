#include "server/service/memory_budget.h"

#include "absl/strings/str_cat.h"

namespace actopo::service {

namespace {

// Whole MiB from 1 MiB up, else KiB, else bytes.
std::string Size(int64_t bytes) {
  if (bytes >= (int64_t(1) << 20)) return absl::StrCat(bytes >> 20, " MiB");
  if (bytes >= 1024) return absl::StrCat(bytes >> 10, " KiB");
  return absl::StrCat(bytes, " bytes");
}

}  // namespace

absl::Status MemoryBudget::Reserve(int64_t bytes, const std::string& what) {
  MutexLock lock(mu_);
  if (used_ + bytes > limit_) {
    return absl::ResourceExhaustedError(
        absl::StrCat(what, " needs about ", Size(bytes), " but the server's ", name_, " has ",
                     Size(limit_ - used_), " left of ", Size(limit_), " (", advice_, ")"));
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
