#include "server/algorithms/vertex_order.h"

#include <algorithm>
#include <numeric>
#include <random>

#include "gtest/gtest.h"
#include "server/core/partition.h"
#include "server/core/testing/status.h"
#include "server/core/testing/test_meshes.h"

namespace actopo {
namespace {

// Against a plain sort of (value, input id), on enough vertices to be sorted in up to 5 runs
// (some merged in place, the last two into the ranks), with many equal values (plateaus are
// ordered by id) and signed zeros (equal).
TEST(VertexOrder, RanksByValueThenInputId) {
  const Mesh mesh = testing::Lattice(80, 70, 60, 3);  // 336,000 vertices: 5 runs of 65,536+
  // Vertices and their permutation are all VertexOrder reads: no faces (a third of the build's
  // time, and most of this test's under TSan).
  auto topo = OkValue(
      Topology::Build(mesh, OctreeBlocks(mesh.points, {.bucket_capacity = 500}), {.faces = false}));
  std::mt19937_64 rng(1);
  std::uniform_int_distribution<int> level(-500, 499);
  std::vector<double> scalars(mesh.num_vertices());
  for (double& s : scalars) s = level(rng) * 0.5;
  for (size_t v = 0; v < scalars.size(); v += 7) scalars[v] = v % 2 ? 0.0 : -0.0;

  std::vector<SimplexId> by_rank(scalars.size());
  std::iota(by_rank.begin(), by_rank.end(), 0);
  std::stable_sort(by_rank.begin(), by_rank.end(),
                   [&](SimplexId a, SimplexId b) { return scalars[a] < scalars[b]; });
  for (int threads : {1, 2, 3, 4, 5}) {
    const std::vector<SimplexId> order = VertexOrder(*topo, scalars, threads);
    for (SimplexId rank = 0; rank < SimplexId(by_rank.size()); ++rank) {
      ASSERT_EQ(order[topo->vertex_internal_id(by_rank[rank])], rank)
          << "rank " << rank << ", threads " << threads;
    }
  }
}

}  // namespace
}  // namespace actopo
