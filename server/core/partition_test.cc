#include "server/core/partition.h"

#include <algorithm>
#include <array>
#include <map>
#include <span>
#include <vector>

#include "gmock/gmock.h"
#include "gtest/gtest.h"
#include "server/core/testing/status.h"
#include "server/core/testing/test_meshes.h"

namespace actopo {
namespace {

TEST(OctreeBlocks, RespectsCapacityAndNumbersDensely) {
  const Mesh m = testing::Lattice(9, 8, 7, 3);
  for (int capacity : {1, 7, 100, 1000}) {
    const std::vector<int32_t> block = OctreeBlocks(m.points, {.bucket_capacity = capacity});
    ASSERT_EQ(block.size(), size_t(m.num_vertices()));
    const int32_t nb = *std::max_element(block.begin(), block.end()) + 1;
    std::vector<int> count(nb, 0);
    for (int32_t b : block) ++count[b];
    for (int32_t b = 0; b < nb; ++b) {
      EXPECT_GT(count[b], 0) << "block " << b << " is empty";
      EXPECT_LE(count[b], capacity) << "block " << b;
    }
    if (capacity >= m.num_vertices()) {
      EXPECT_EQ(nb, 1);
    }
  }
}

TEST(OctreeBlocks, BlocksAreSpatiallyCompact) {
  // A 8x8x8 lattice with capacity 64 splits into 8 octants of 4x4x4 each.
  const Mesh m = testing::Lattice(8, 8, 8);
  const std::vector<int32_t> block = OctreeBlocks(m.points, {.bucket_capacity = 64});
  for (SimplexId v = 0; v < m.num_vertices(); ++v) {
    const int octant = (m.points[3 * v] >= 3.5) + 2 * (m.points[3 * v + 1] >= 3.5) +
                       4 * (m.points[3 * v + 2] >= 3.5);
    EXPECT_EQ(block[v], octant) << "vertex " << v;  // Morton order, x fastest
  }
}

// The PR-octree by its definition, one node at a time: a node of more than `capacity` vertices
// (above max_depth) splits at its cell's centre into 8 children in Morton order, and leaves are
// numbered depth first.
void ReferenceOctree(std::span<const double> points, const std::vector<int32_t>& ids,
                     std::array<double, 3> lo, std::array<double, 3> hi, int depth,
                     const OctreeOptions& options, int32_t& next, std::vector<int32_t>& block) {
  if (ids.empty()) return;
  if (int64_t(ids.size()) <= options.bucket_capacity || depth >= options.max_depth) {
    for (int32_t v : ids) block[v] = next;
    ++next;
    return;
  }
  std::array<double, 3> mid;
  for (int k = 0; k < 3; ++k) mid[k] = 0.5 * (lo[k] + hi[k]);
  for (int child = 0; child < 8; ++child) {
    std::vector<int32_t> inside;
    for (int32_t v : ids) {
      int c = 0;
      for (int k = 0; k < 3; ++k) c |= (points[3 * size_t(v) + k] >= mid[k]) << k;
      if (c == child) inside.push_back(v);
    }
    std::array<double, 3> clo = lo, chi = hi;
    for (int k = 0; k < 3; ++k) (child >> k & 1 ? clo[k] : chi[k]) = mid[k];
    ReferenceOctree(points, inside, clo, chi, depth + 1, options, next, block);
  }
}

// Built in parallel subtrees, the blocks are the reference's, numbered the same.
TEST(OctreeBlocks, EqualsTheOctreeByDefinition) {
  const Mesh m = testing::Lattice(31, 29, 27, 11);
  const SimplexId n = m.num_vertices();
  std::array<double, 3> lo{1e300, 1e300, 1e300}, hi{-1e300, -1e300, -1e300};
  for (SimplexId v = 0; v < n; ++v) {
    for (int k = 0; k < 3; ++k) {
      lo[k] = std::min(lo[k], m.points[3 * v + k]);
      hi[k] = std::max(hi[k], m.points[3 * v + k]);
    }
  }
  const double side = std::max({hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]});
  for (int k = 0; k < 3; ++k) hi[k] = lo[k] + side;
  std::vector<int32_t> all(n);
  for (SimplexId v = 0; v < n; ++v) all[v] = v;
  for (int capacity : {1, 13, 100, 5000}) {
    const OctreeOptions options{.bucket_capacity = capacity};
    std::vector<int32_t> expected(n, -1);
    int32_t next = 0;
    ReferenceOctree(m.points, all, lo, hi, 0, options, next, expected);
    EXPECT_EQ(OctreeBlocks(m.points, options), expected) << "capacity " << capacity;
  }
}

TEST(OctreeBlocks, CoincidentPointsStopAtMaxDepth) {
  std::vector<double> points(3 * 50, 1.0);
  const std::vector<int32_t> block = OctreeBlocks(points, {.bucket_capacity = 1, .max_depth = 10});
  EXPECT_EQ(*std::max_element(block.begin(), block.end()), 0);
}

TEST(LabelBlocks, RenumbersDensely) {
  const std::vector<double> labels = {7, -2, 7, 100, -2};
  EXPECT_THAT(OkValue(LabelBlocks(labels)), ::testing::ElementsAre(1, 0, 1, 2, 0));
  const std::vector<double> bad = {1, 2.5};
  EXPECT_THAT(LabelBlocks(bad).status().message(), ::testing::HasSubstr("vertex 1 has label 2.5"));
}

}  // namespace
}  // namespace actopo
