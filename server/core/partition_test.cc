#include "server/core/partition.h"

#include <algorithm>
#include <map>

#include "gmock/gmock.h"
#include "gtest/gtest.h"
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

TEST(OctreeBlocks, CoincidentPointsStopAtMaxDepth) {
  std::vector<double> points(3 * 50, 1.0);
  const std::vector<int32_t> block = OctreeBlocks(points, {.bucket_capacity = 1, .max_depth = 10});
  EXPECT_EQ(*std::max_element(block.begin(), block.end()), 0);
}

TEST(LabelBlocks, RenumbersDensely) {
  const std::vector<double> labels = {7, -2, 7, 100, -2};
  EXPECT_THAT(*LabelBlocks(labels), ::testing::ElementsAre(1, 0, 1, 2, 0));
  const std::vector<double> bad = {1, 2.5};
  EXPECT_THAT(LabelBlocks(bad).status().message(), ::testing::HasSubstr("vertex 1 has label 2.5"));
}

}  // namespace
}  // namespace actopo
