#include "server/algorithms/gradient_paths.h"

#include <vector>

#include "gtest/gtest.h"
#include "server/algorithms/vertex_order.h"
#include "server/core/explicit_structure.h"
#include "server/core/partition.h"
#include "server/core/testing/status.h"
#include "server/core/testing/test_meshes.h"

namespace actopo {
namespace {

// Every vertex's descending path, walked step by step by hand from the pairings: WalkDown
// reports the same edges and vertices, each step lower in the order, and ends where
// DescendToMinimum does, at a critical vertex.
TEST(GradientPaths, WalkDownFollowsTheVertexEdgePairsToAMinimum) {
  const Mesh mesh = testing::Lattice(6, 5, 4, /*shuffle_seed=*/7);
  const auto topo =
      OkValue(Topology::Build(mesh, OctreeBlocks(mesh.points, {.bucket_capacity = 16})));
  const std::vector<SimplexId> order = VertexOrder(*topo, mesh.point_fields[0].values);
  auto structure = OkValue(ExplicitStructure::Build(topo, {}));
  const DiscreteGradientResult r =
      OkValue(RunDiscreteGradient(*structure, order, {}, GradientArrays::kPaths));
  const GradientField& g = r.gradient;
  int64_t steps = 0;
  for (SimplexId v = 0; v < topo->num_vertices(); ++v) {
    std::vector<SimplexId> expected;  // edge, vertex, edge, vertex ...
    for (SimplexId at = v; !g.IsCritical(0, at);) {
      const SimplexId e = g.up[0][at];
      const auto ev = topo->edge(e);
      ASSERT_TRUE(ev[0] == at || ev[1] == at);
      at = ev[0] == at ? ev[1] : ev[0];
      expected.insert(expected.end(), {e, at});
    }
    std::vector<SimplexId> walked;
    SimplexId previous = v;
    const SimplexId minimum = WalkDown(*topo, g, v, [&](SimplexId edge, SimplexId next) {
      EXPECT_LT(order[next], order[previous]) << "a step up from vertex " << previous;
      EXPECT_EQ(next, NextVertexDown(*topo, g, previous));
      previous = next;
      walked.insert(walked.end(), {edge, next});
    });
    EXPECT_EQ(walked, expected) << "vertex " << v;
    EXPECT_TRUE(g.IsCritical(0, minimum));
    EXPECT_EQ(minimum, DescendToMinimum(*topo, g, v));
    steps += int64_t(walked.size() / 2);
  }
  EXPECT_GT(steps, topo->num_vertices());  // the paths are not all trivial
}

TEST(GradientPaths, LinkCodesAreBelowEveryIdAndTheirOwnInverse) {
  EXPECT_EQ(LinkCode::Code(-1), LinkCode::kBoundary);
  for (SimplexId label : {0, 1, 7, 1 << 30}) {
    EXPECT_LT(LinkCode::Code(label), LinkCode::kBoundary);
    EXPECT_TRUE(LinkCode::IsEnd(LinkCode::Code(label)));
    EXPECT_EQ(LinkCode::Label(LinkCode::Code(label)), label);
  }
  EXPECT_FALSE(LinkCode::IsEnd(0));
}

// Two chains over six tetrahedra: 0 -> 2 -> 4 -> maximum 3, and 1 -> 5 -> the boundary.
TEST(GradientPaths, ClimbLinksFollowsTheLinksToTheirCode) {
  const std::vector<SimplexId> up = {2, 5, 4, 3, LinkCode::Code(3), LinkCode::kBoundary};
  std::vector<std::pair<SimplexId, SimplexId>> moves;
  const auto record = [&](SimplexId from, SimplexId to) { moves.emplace_back(from, to); };
  EXPECT_EQ(LinkCode::Label(ClimbLinks(up, 0, record)), 3);
  EXPECT_EQ(moves, (std::vector<std::pair<SimplexId, SimplexId>>{{0, 2}, {2, 4}}));
  moves.clear();
  EXPECT_EQ(ClimbLinks(up, 1, record), LinkCode::kBoundary);
  EXPECT_EQ(moves, (std::vector<std::pair<SimplexId, SimplexId>>{{1, 5}}));
  moves.clear();
  EXPECT_EQ(ClimbLinks(up, 4, record), LinkCode::Code(3));
  EXPECT_TRUE(moves.empty());
}

}  // namespace
}  // namespace actopo
