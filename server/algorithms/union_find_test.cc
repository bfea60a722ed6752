#include "server/algorithms/union_find.h"

#include <random>
#include <vector>

#include "gtest/gtest.h"

namespace actopo {
namespace {

// Against relabelling, the brute-force oracle: after each union every element of the two sets
// takes one label, and two elements share a root exactly when they share a label.
TEST(UnionFind, AgreesWithRelabellingUnderRandomUnions) {
  for (const uint32_t seed : {1u, 2u, 3u}) {
    const int32_t n = 200;
    std::mt19937 rng(seed);
    std::uniform_int_distribution<int32_t> pick(0, n - 1);
    UnionFind sets(n);
    std::vector<int32_t> label(n);
    for (int32_t i = 0; i < n; ++i) label[i] = i;
    for (int step = 0; step < 300; ++step) {
      const int32_t a = pick(rng), b = pick(rng);
      const int32_t root = sets.Union(a, b);
      EXPECT_EQ(root, sets.Find(b));
      EXPECT_TRUE(sets.IsRoot(root));
      const int32_t from = label[a], to = label[b];
      for (int32_t& l : label) {
        if (l == from) l = to;
      }
      for (int32_t k = 0; k < 20; ++k) {
        const int32_t x = pick(rng), y = pick(rng);
        EXPECT_EQ(sets.Find(x) == sets.Find(y), label[x] == label[y])
            << "seed " << seed << ", step " << step << ": " << x << " and " << y;
      }
    }
  }
}

// The caller decides which root survives a Link; later finds (which compress paths) keep it.
TEST(UnionFind, LinkKeepsTheChosenRoot) {
  UnionFind sets(6);
  sets.Link(0, 1);
  sets.Link(1, 2);
  sets.Link(5, 4);
  sets.Link(4, 2);
  for (int32_t x : {0, 1, 2, 4, 5}) EXPECT_EQ(sets.Find(x), 2) << x;
  EXPECT_EQ(sets.Find(0), 2);  // again, after the compression
  EXPECT_EQ(sets.Find(3), 3);
  sets.Reset(3);
  EXPECT_EQ(sets.size(), 3u);
  for (int32_t x = 0; x < 3; ++x) EXPECT_TRUE(sets.IsRoot(x));
}

}  // namespace
}  // namespace actopo
