#include "server/core/process_memory.h"

#include <cstring>
#include <memory>

#include "gtest/gtest.h"

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

}  // namespace
}  // namespace actopo
