// Sorting (high, low) pairs of 32-bit ids packed as high << 32 | low, where many pairs share
// their high id's neighbourhood: the Morse-Smale walls' (edge, triangle) pairs.
//
//   std::vector<uint64_t> keys = ..., scratch;
//   SortPairKeys(keys, scratch);  // ascending, as std::sort; scratch is reused between calls
#ifndef ACTOPO_SERVER_ALGORITHMS_PAIR_KEYS_H_
#define ACTOPO_SERVER_ALGORITHMS_PAIR_KEYS_H_

#include <algorithm>
#include <array>
#include <bit>
#include <cstdint>
#include <utility>
#include <vector>

namespace actopo {

// Ascending. Lists of kPairKeysRadixMin keys and more go through a least-significant-digit radix
// sort on the high ids' offsets from the lowest (11 bits a pass: a wall spanning two million
// edge ids takes two passes), then each high id's few keys are put in order in place. A wall
// can hold tens of thousands of triangles, where std::sort's comparisons would be a visible
// share of the whole Morse-Smale run.
inline constexpr size_t kPairKeysRadixMin = 1024;

inline void SortPairKeys(std::vector<uint64_t>& keys, std::vector<uint64_t>& scratch) {
  if (keys.size() < kPairKeysRadixMin) {
    std::sort(keys.begin(), keys.end());
    return;
  }
  constexpr int kDigitBits = 11;
  constexpr uint32_t kDigits = 1u << kDigitBits;
  uint32_t low = UINT32_MAX, high = 0;
  for (const uint64_t k : keys) {
    low = std::min(low, uint32_t(k >> 32));
    high = std::max(high, uint32_t(k >> 32));
  }
  const int bits = std::bit_width(high - low);
  scratch.resize(keys.size());
  for (int shift = 0; shift < bits; shift += kDigitBits) {
    const auto digit = [&](uint64_t k) {
      return ((uint32_t(k >> 32) - low) >> shift) & (kDigits - 1);
    };
    std::array<uint32_t, kDigits> start{};
    for (const uint64_t k : keys) ++start[digit(k)];
    uint32_t sum = 0;
    for (uint32_t& n : start) sum += std::exchange(n, sum);
    for (const uint64_t k : keys) scratch[start[digit(k)]++] = k;
    keys.swap(scratch);
  }
  // Sorted by high id: a key moves only past the keys of its own high id.
  for (size_t i = 1; i < keys.size(); ++i) {
    const uint64_t k = keys[i];
    size_t j = i;
    for (; j > 0 && keys[j - 1] > k; --j) keys[j] = keys[j - 1];
    keys[j] = k;
  }
}

}  // namespace actopo

#endif  // ACTOPO_SERVER_ALGORITHMS_PAIR_KEYS_H_
