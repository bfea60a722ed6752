#include "server/core/process_memory.h"

#include <sys/mman.h>
#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#if defined(__GLIBC__)
#include <malloc.h>
#endif

// Under a sanitizer, its own allocator serves malloc and glibc's statistics stay empty.
#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
#define ACTOPO_SANITIZER_ALLOCATOR 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer) || __has_feature(thread_sanitizer)
#define ACTOPO_SANITIZER_ALLOCATOR 1
#endif
#endif
#if defined(ACTOPO_SANITIZER_ALLOCATOR)
extern "C" size_t __sanitizer_get_current_allocated_bytes();  // sanitizer/allocator_interface.h
#endif

namespace actopo {

int64_t PeakRssBytes() {
  struct rusage usage {};
  if (getrusage(RUSAGE_SELF, &usage) != 0) return 0;
  return int64_t(usage.ru_maxrss) * 1024;  // Linux reports kilobytes
}

int64_t CurrentRssBytes() {
  std::FILE* f = std::fopen("/proc/self/statm", "r");
  if (f == nullptr) return 0;
  long long pages_total = 0, pages_resident = 0;
  const int n = std::fscanf(f, "%lld %lld", &pages_total, &pages_resident);
  std::fclose(f);
  return n == 2 ? pages_resident * int64_t(sysconf(_SC_PAGESIZE)) : 0;
}

int64_t HeapInUseBytes() {
#if defined(ACTOPO_SANITIZER_ALLOCATOR)
  return int64_t(__sanitizer_get_current_allocated_bytes());
#elif defined(__GLIBC__) && (__GLIBC__ > 2 || (__GLIBC__ == 2 && __GLIBC_MINOR__ >= 33))
  const struct mallinfo2 info = mallinfo2();
  return int64_t(info.uordblks + info.hblkhd);  // chunks in use in the arenas, and mmapped ones
#else
  return 0;
#endif
}

void ReleaseFreeMemory() {
#if defined(__GLIBC__)
  malloc_trim(0);
#endif
}

void ConfigureAllocator(int cores) {
#if defined(__GLIBC__)
  const char* tunables = std::getenv("GLIBC_TUNABLES");
  const auto tuned = [tunables](const char* name) {
    return tunables != nullptr && std::strstr(tunables, name) != nullptr;
  };
  if (std::getenv("MALLOC_ARENA_MAX") == nullptr && !tuned("glibc.malloc.arena_max")) {
    mallopt(M_ARENA_MAX, std::max(cores, 1));
  }
  if (std::getenv("MALLOC_MMAP_THRESHOLD_") == nullptr && !tuned("glibc.malloc.mmap_threshold")) {
    mallopt(M_MMAP_THRESHOLD, int(kMmapThresholdBytes));
  }
#else
  (void)cores;
#endif
}

void ReleasePages(const void* begin, const void* end) {
  static const uintptr_t page = uintptr_t(sysconf(_SC_PAGESIZE));
  const uintptr_t from = (reinterpret_cast<uintptr_t>(begin) + page - 1) & ~(page - 1);
  const uintptr_t to = reinterpret_cast<uintptr_t>(end) & ~(page - 1);
  if (to > from) madvise(reinterpret_cast<void*>(from), to - from, MADV_DONTNEED);
}

}  // namespace actopo
