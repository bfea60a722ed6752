#include "server/algorithms/consumers.h"

#include <algorithm>
#include <thread>
#include <vector>

#include "gtest/gtest.h"

namespace actopo {
namespace {

// One party: chunks of `chunk` items while at least two chunks are left, then half of what is
// left each time, down to single items; every item once, in ascending order.
TEST(ItemQueue, ShrinksItsChunksToTheShareLeft) {
  ItemQueue queue(100, 16);
  std::vector<int64_t> sizes;
  int64_t begin, end, expected = 0;
  while (queue.Next(begin, end)) {
    EXPECT_EQ(begin, expected);
    sizes.push_back(end - begin);
    expected = end;
  }
  EXPECT_EQ(expected, 100);
  EXPECT_EQ(sizes, (std::vector<int64_t>{16, 16, 16, 16, 16, 10, 5, 2, 1, 1, 1}));
}

// Parties taking chunks at once get every item exactly once, and no chunk is larger than the
// items left divided among twice the parties when it was taken.
TEST(ItemQueue, HandsOutEveryItemOnceToConcurrentParties) {
  constexpr int kParties = 4;
  constexpr int64_t kItems = 100000;
  ItemQueue queue(kItems, 1000, kParties);
  std::vector<std::vector<std::pair<int64_t, int64_t>>> taken(kParties);
  std::vector<std::thread> threads;
  for (int p = 0; p < kParties; ++p) {
    threads.emplace_back([&, p] {
      int64_t begin, end;
      while (queue.Next(begin, end)) taken[p].emplace_back(begin, end);
    });
  }
  for (std::thread& t : threads) t.join();
  std::vector<std::pair<int64_t, int64_t>> all;
  for (const auto& t : taken) all.insert(all.end(), t.begin(), t.end());
  std::sort(all.begin(), all.end());
  int64_t expected = 0;
  for (const auto& [begin, end] : all) {
    ASSERT_EQ(begin, expected);
    ASSERT_GT(end, begin);
    EXPECT_LE(end - begin, std::max<int64_t>(1, std::min<int64_t>(1000, (kItems - begin) / 8)));
    expected = end;
  }
  EXPECT_EQ(expected, kItems);
}

}  // namespace
}  // namespace actopo
