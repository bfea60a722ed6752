#include "server/core/process_memory.h"

#include <cstdlib>
#include <cstring>
#include <memory>

#include "gtest/gtest.h"
#include "tests/testing/skip.h"

#if defined(__has_feature)
#define ACTOPO_CLANG_SANITIZER (__has_feature(address_sanitizer) || __has_feature(thread_sanitizer))
#else
#define ACTOPO_CLANG_SANITIZER 0
#endif

namespace actopo {
namespace {

// The heap figure follows what is allocated and freed, whatever the allocator keeps resident.
TEST(ProcessMemory, HeapInUseCountsAllocationsUntilTheyAreFreed) {
  constexpr int64_t kBytes = int64_t(64) << 20;
  const int64_t before = HeapInUseBytes();
  ASSERT_GT(before, 0) << "no allocator statistics on this platform";
  auto block = std::make_unique<char[]>(kBytes);
  std::memset(block.get(), 1, kBytes);  // resident, so RSS grows by as much
  const int64_t held = HeapInUseBytes();
  EXPECT_GE(held - before, kBytes);
  EXPECT_GE(CurrentRssBytes(), kBytes);
  block.reset();
  EXPECT_LT(HeapInUseBytes(), held - kBytes / 2);
  EXPECT_GE(PeakRssBytes(), kBytes);
}

// A freed mesh-sized array leaves the process at once, even after glibc would have raised its
// mapping threshold above that size (and served the next such array from the heap, to stay).
// glibc's allocator only: a sanitizer's keeps freed memory in quarantine.
#if defined(__GLIBC__) && !defined(__SANITIZE_ADDRESS__) && !defined(__SANITIZE_THREAD__) && \
    !ACTOPO_CLANG_SANITIZER
TEST(ProcessMemory, ConfiguredAllocatorHandsLargeArraysBackWhenFreed) {
  if (std::getenv("MALLOC_MMAP_THRESHOLD_") != nullptr || std::getenv("GLIBC_TUNABLES") != nullptr)
    ACTOPO_SKIP() << "the environment sets the allocator";
  ConfigureAllocator(2);
  constexpr size_t kBytes = size_t(24) << 20;
  {  // glibc's own rule would raise its threshold above kBytes when this one is freed
    auto first = std::make_unique<char[]>(kBytes);
    std::memset(first.get(), 1, kBytes);
  }
  auto second = std::make_unique<char[]>(kBytes);
  std::memset(second.get(), 1, kBytes);
  const int64_t held = CurrentRssBytes();
  second.reset();
  EXPECT_LT(CurrentRssBytes(), held - int64_t(kBytes) / 2);
}
#endif

}  // namespace
}  // namespace actopo
