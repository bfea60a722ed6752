#include "server/service/ids.h"

#include <cstdio>
#include <random>

#include "server/core/sync.h"

namespace actopo::service {

std::string NewId(const std::string& prefix) {
  static Mutex mu;
  static std::random_device device ABSL_GUARDED_BY(mu);  // /dev/urandom on Linux
  uint32_t words[4];
  {
    MutexLock lock(mu);
    for (uint32_t& w : words) w = device();
  }
  char hex[33];
  std::snprintf(hex, sizeof hex, "%08x%08x%08x%08x", words[0], words[1], words[2], words[3]);
  return prefix + "-" + hex;
}

}  // namespace actopo::service
