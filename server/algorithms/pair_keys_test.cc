#include "server/algorithms/pair_keys.h"

#include <algorithm>
#include <random>
#include <vector>

#include "gtest/gtest.h"

namespace actopo {
namespace {

// Random (high, low) keys: `count` of them, high ids in [base, base + span), a few keys per
// high id as walls have, low ids anywhere.
std::vector<uint64_t> RandomKeys(size_t count, uint32_t base, uint32_t span, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_int_distribution<uint32_t> high(0, span - 1), low;
  std::vector<uint64_t> keys(count);
  for (uint64_t& k : keys) k = uint64_t(base + high(rng)) << 32 | low(rng);
  return keys;
}

TEST(SortPairKeys, SortsAsStdSortOnEitherSideOfTheRadixThreshold) {
  std::vector<uint64_t> scratch;
  uint32_t seed = 1;
  for (const size_t count : {size_t(0), size_t(1), kPairKeysRadixMin - 1, kPairKeysRadixMin,
                             size_t(5000), size_t(20000)}) {
    // Spans of one high id (no radix pass), one digit, two and three digits, and high ids near
    // the top of the 32 bits.
    for (const auto& [base, span] : std::vector<std::pair<uint32_t, uint32_t>>{
             {7, 1}, {1000, 2000}, {0, 3'000'000}, {0xFFFF0000u, 0xFFFFu}, {0, 0xFFFFFFFFu}}) {
      std::vector<uint64_t> keys = RandomKeys(count, base, span, seed++);
      std::vector<uint64_t> expected = keys;
      std::sort(expected.begin(), expected.end());
      SortPairKeys(keys, scratch);
      EXPECT_EQ(keys, expected) << count << " keys, high ids from " << base << " over " << span;
    }
  }
}

TEST(SortPairKeys, KeepsRepeatedKeys) {
  std::vector<uint64_t> keys(3000, uint64_t(5) << 32 | 9), scratch;
  keys[10] = uint64_t(4) << 32 | 2;
  keys[2000] = uint64_t(6) << 32;
  SortPairKeys(keys, scratch);
  EXPECT_EQ(keys.front(), uint64_t(4) << 32 | 2);
  EXPECT_EQ(keys.back(), uint64_t(6) << 32);
  EXPECT_EQ(std::count(keys.begin(), keys.end(), uint64_t(5) << 32 | 9), 2998);
}

}  // namespace
}  // namespace actopo
