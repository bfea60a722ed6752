#include "server/algorithms/topological_simplification.h"

#include <algorithm>
#include <cstdlib>
#include <random>
#include <set>

#include "gtest/gtest.h"
#include "server/algorithms/discrete_gradient.h"
#include "server/algorithms/vertex_order.h"
#include "server/core/actopo_structure.h"
#include "server/core/compact_structure.h"
#include "server/core/explicit_structure.h"
#include "server/core/partition.h"
#include "server/core/testing/status.h"
#include "server/core/testing/test_meshes.h"

namespace actopo {
namespace {

struct Input {
  Mesh mesh;
  std::shared_ptr<const Topology> topo;
  std::vector<SimplexId> order;
  std::vector<double> scalars;
};

// A lattice with a noisy field: many extrema of low persistence around a few big ones.
Input Noisy(int n, uint64_t seed, int block_size = 40) {
  Input in{testing::Lattice(n, n, n, seed)};
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> noise(0, 0.15);
  in.scalars = in.mesh.point_fields[0].values;
  for (double& v : in.scalars) v += noise(rng);
  in.mesh.point_fields[0].values = in.scalars;
  in.topo = OkValue(
      Topology::Build(in.mesh, OctreeBlocks(in.mesh.points, {.bucket_capacity = block_size})));
  in.order = VertexOrder(*in.topo, in.scalars);
  return in;
}

// Input ids of the local minima and maxima of an order given by input id (lower link empty,
// upper link empty).
std::pair<std::set<SimplexId>, std::set<SimplexId>> Extrema(const Input& in, auto& structure,
                                                            std::span<const SimplexId> by_input) {
  auto reader = structure.NewReader();
  std::set<SimplexId> minima, maxima;
  const Topology& topo = *in.topo;
  for (SimplexId v = 0; v < topo.num_vertices(); ++v) {
    bool lower = false, higher = false;
    const SimplexId mine = by_input[topo.vertex_input_id(v)];
    for (SimplexId u : reader.vertex_neighbors(v)) {
      (by_input[topo.vertex_input_id(u)] < mine ? lower : higher) = true;
    }
    if (!lower) minima.insert(topo.vertex_input_id(v));
    if (!higher) maxima.insert(topo.vertex_input_id(v));
  }
  return {minima, maxima};
}

// What TTK guarantees: the simplified field's extrema are exactly the extrema among the kept
// pairs' vertices (saddle-saddle pairs are not controlled); the rest is flattened to saddles.
TEST(TopologicalSimplification, KeepsExactlyTheExtremaOfTheKeptPairs) {
  const Input in = Noisy(9, 5);
  auto structure = OkValue(ExplicitStructure::Build(in.topo, {}));
  std::vector<SimplexId> input_order(in.order.size());
  for (SimplexId v = 0; v < in.topo->num_vertices(); ++v) {
    input_order[in.topo->vertex_input_id(v)] = in.order[v];
  }
  const auto [minima_before, maxima_before] = Extrema(in, *structure, input_order);
  for (const auto& [fraction, legacy] :
       {std::pair{0.02, false}, std::pair{0.1, false}, std::pair{0.3, false}, std::pair{0.02, true},
        std::pair{0.3, true}}) {
    SCOPED_TRACE(::testing::Message() << fraction << (legacy ? " legacy" : " lts"));
    const auto r = RunTopologicalSimplification(
        *structure, in.order, in.scalars,
        {.threshold = fraction, .relative = true, .legacy = legacy}, {});
    ASSERT_TRUE(r.ok()) << r.status();
    std::set<SimplexId> kept;
    for (const PersistencePair& p : r->diagram.pairs) {
      if (p.Persistence() >= r->threshold) kept.insert({p.birth, p.death});
    }
    std::set<SimplexId> want_minima, want_maxima;
    for (SimplexId v : kept) {
      if (minima_before.contains(v)) want_minima.insert(v);
      if (maxima_before.contains(v)) want_maxima.insert(v);
    }
    const auto [minima, maxima] = Extrema(in, *structure, r->order);
    EXPECT_EQ(minima, want_minima);
    EXPECT_EQ(maxima, want_maxima);
    EXPECT_LT(minima.size() + maxima.size(), minima_before.size() + maxima_before.size());
    EXPECT_EQ(r->stats.minima, int64_t(minima.size()));
    EXPECT_EQ(r->stats.maxima, int64_t(maxima.size()));
    // Values change only by flattening to a value the field had, and the order stays a
    // permutation consistent with the values.
    std::set<double> values(in.scalars.begin(), in.scalars.end());
    int64_t changed = 0;
    for (size_t v = 0; v < in.scalars.size(); ++v) {
      EXPECT_TRUE(values.contains(r->scalars[v]));
      changed += r->scalars[v] != in.scalars[v];
    }
    EXPECT_EQ(changed, r->stats.changed_values);
    EXPECT_GT(changed, 0);
    std::vector<SimplexId> by_rank(in.scalars.size());
    std::vector<bool> seen(in.scalars.size(), false);
    for (size_t v = 0; v < r->order.size(); ++v) {
      ASSERT_FALSE(seen[r->order[v]]);
      seen[r->order[v]] = true;
      by_rank[r->order[v]] = SimplexId(v);
    }
    for (size_t i = 1; i < by_rank.size(); ++i) {
      EXPECT_LE(r->scalars[by_rank[i - 1]], r->scalars[by_rank[i]]);
    }
  }
}

// Threshold 0 keeps every pair; as in TTK, the field still loses the PL extrema that the
// gradient pairs away inside a lower star (no pair stands for them), and keeps every other.
TEST(TopologicalSimplification, ThresholdZeroKeepsEveryPair) {
  const Input in = Noisy(6, 3);
  auto structure = OkValue(ExplicitStructure::Build(in.topo, {}));
  const auto r = OkValue(RunTopologicalSimplification(*structure, in.order, in.scalars, {}, {}));
  EXPECT_EQ(r.stats.removed_pairs, 0);
  EXPECT_EQ(r.stats.kept_pairs, int64_t(r.diagram.pairs.size()));
  EXPECT_EQ(r.stats.minima, r.diagram.gradient.critical_cells[0]);
  EXPECT_LE(r.stats.changed_values, int64_t(in.scalars.size()) / 10);
}

TEST(TopologicalSimplification, DoesNotDependOnTheStructureThreadsOrBlocks) {
  const Input in = Noisy(8, 11);
  const SimplificationOptions options{.threshold = 0.05, .relative = true};
  auto explicit_structure = OkValue(ExplicitStructure::Build(in.topo, {}));
  const auto reference =
      OkValue(RunTopologicalSimplification(*explicit_structure, in.order, in.scalars, options, {}));
  const auto digests = [](const SimplificationResult& r) {
    return std::make_pair(r.ScalarsDigest(), r.OrderDigest());
  };
  ASSERT_GT(reference.stats.changed_values, 0);
  for (int consumers : {1, 2, 3}) {
    const RunContext context{.consumers = consumers};
    CompactStructure compact(in.topo, {.cache_ratio = 0.05, .consumers = consumers});
    EXPECT_EQ(digests(OkValue(
                  RunTopologicalSimplification(compact, in.order, in.scalars, options, context))),
              digests(reference));
    auto actopo = OkValue(
        ActopoStructure::Create(in.topo, {.consumers = consumers,
                                          .producers = 2,
                                          .buffer_ratio = 0.05,
                                          .declared = TopologicalSimplificationDeclared()}));
    EXPECT_EQ(digests(OkValue(
                  RunTopologicalSimplification(*actopo, in.order, in.scalars, options, context))),
              digests(reference));
  }
  const Input other = Noisy(8, 11, /*block_size=*/7);
  auto s = OkValue(ExplicitStructure::Build(other.topo, {}));
  EXPECT_EQ(
      digests(OkValue(RunTopologicalSimplification(*s, other.order, other.scalars, options, {}))),
      digests(reference));
}

void ExpectSameGradient(const DiscreteGradientResult& got, const DiscreteGradientResult& want) {
  for (int d = 0; d < 4; ++d) {
    EXPECT_EQ(got.gradient.up[d], want.gradient.up[d]) << "up " << d;
    EXPECT_EQ(got.gradient.down[d], want.gradient.down[d]) << "down " << d;
    EXPECT_EQ(got.critical[d], want.critical[d]) << "critical " << d;
  }
  EXPECT_EQ(got.critical_cells, want.critical_cells);
  EXPECT_EQ(got.pairs, want.pairs);
}

// LTS moves only the vertices it flattens: every two others compare as in the input order.
TEST(TopologicalSimplification, ReorderedHoldsEveryVertexWhoseOrderMoved) {
  const Input in = Noisy(9, 5);
  auto structure = OkValue(ExplicitStructure::Build(in.topo, {}));
  for (double fraction : {0.02, 0.1, 0.3}) {
    SCOPED_TRACE(fraction);
    const auto r = OkValue(RunTopologicalSimplification(
        *structure, in.order, in.scalars, {.threshold = fraction, .relative = true}, {}));
    ASSERT_FALSE(r.reordered.empty());
    EXPECT_TRUE(std::is_sorted(r.reordered.begin(), r.reordered.end()));
    std::vector<SimplexId> kept;  // the others, by input order
    for (SimplexId v = 0; v < in.topo->num_vertices(); ++v) {
      if (!std::binary_search(r.reordered.begin(), r.reordered.end(), v)) kept.push_back(v);
    }
    std::sort(kept.begin(), kept.end(),
              [&](SimplexId a, SimplexId b) { return in.order[a] < in.order[b]; });
    for (size_t i = 1; i < kept.size(); ++i) {
      ASSERT_LT(r.internal_order[kept[i - 1]], r.internal_order[kept[i]]);
    }
    // Each flattened vertex moved: none was left where it was among the others.
    EXPECT_LT(kept.size(), size_t(in.topo->num_vertices()));
    // The changed lower stars, every vertex checked: the flattened vertices and each vertex
    // whose lower neighbours, listed lowest first, differ between the two orders.
    auto reader = structure->NewReader();
    const auto lower_link = [&](SimplexId v, std::span<const SimplexId> order) {
      std::vector<SimplexId> link;
      for (SimplexId u : reader.vertex_neighbors(v)) {
        if (order[u] < order[v]) link.push_back(u);
      }
      std::sort(link.begin(), link.end(),
                [&](SimplexId a, SimplexId b) { return order[a] < order[b]; });
      return link;
    };
    std::vector<SimplexId> changed;
    for (SimplexId v = 0; v < in.topo->num_vertices(); ++v) {
      if (std::binary_search(r.reordered.begin(), r.reordered.end(), v) ||
          lower_link(v, in.order) != lower_link(v, r.internal_order)) {
        changed.push_back(v);
      }
    }
    EXPECT_EQ(r.changed_stars, changed);
    EXPECT_GT(r.changed_stars.size(), r.reordered.size());
  }
  const auto legacy = OkValue(RunTopologicalSimplification(
      *structure, in.order, in.scalars, {.threshold = 0.1, .relative = true, .legacy = true}, {}));
  EXPECT_TRUE(legacy.reordered.empty());
}

// The diagram's gradient, updated around the flattened vertices, is the simplified order's
// gradient computed from scratch: on every structure and consumer count, from either set of
// arrays.
TEST(TopologicalSimplification, UpdatedGradientEqualsTheSimplifiedOrdersGradient) {
  const Input in = Noisy(10, 17, /*block_size=*/25);
  auto explicit_structure = OkValue(ExplicitStructure::Build(in.topo, {}));
  for (double fraction : {0.0, 0.02, 0.1, 0.3}) {
    SCOPED_TRACE(fraction);
    const auto r = OkValue(RunTopologicalSimplification(
        *explicit_structure, in.order, in.scalars, {.threshold = fraction, .relative = true}, {}));
    const std::vector<SimplexId>& order = r.internal_order;
    const auto want =
        OkValue(RunDiscreteGradient(*explicit_structure, order, {}, GradientArrays::kAll));
    // The diagram's gradient keeps the persistence arrays, and so does its update.
    const auto want_kept =
        OkValue(RunDiscreteGradient(*explicit_structure, order, {}, GradientArrays::kPersistence));
    if (fraction > 0) {
      ASSERT_LT(r.reordered.size(), size_t(in.topo->num_vertices()) / 2);
      ASSERT_NE(want.gradient.up[0], r.diagram.gradient.gradient.up[0]);  // something to update
    }
    ExpectSameGradient(OkValue(UpdateDiscreteGradient(*explicit_structure, r.diagram.gradient,
                                                      order, r.reordered, {})),
                       want_kept);
    const auto full_before =
        OkValue(RunDiscreteGradient(*explicit_structure, in.order, {}, GradientArrays::kAll));
    ExpectSameGradient(
        OkValue(UpdateDiscreteGradient(*explicit_structure, full_before, order, r.reordered, {})),
        want);
    for (int consumers : {1, 2, 3}) {
      SCOPED_TRACE(consumers);
      const RunContext context{.consumers = consumers};
      CompactStructure compact(in.topo, {.cache_ratio = 0.05, .consumers = consumers});
      ExpectSameGradient(
          OkValue(UpdateDiscreteGradient(compact, r.diagram.gradient, order, r.reordered, context)),
          want_kept);
      auto actopo =
          OkValue(ActopoStructure::Create(in.topo, {.consumers = consumers,
                                                    .producers = 2,
                                                    .buffer_ratio = 0.05,
                                                    .declared = DiscreteGradientDeclared()}));
      ExpectSameGradient(
          OkValue(UpdateDiscreteGradient(*actopo, r.diagram.gradient, order, r.reordered, context)),
          want_kept);
      // Only the changed stars, given instead of read.
      ExpectSameGradient(OkValue(UpdateDiscreteGradient(*actopo, r.diagram.gradient, order,
                                                        r.reordered, context, r.changed_stars)),
                         want_kept);
      ExpectSameGradient(OkValue(UpdateDiscreteGradient(*actopo, full_before, order, r.reordered,
                                                        context, r.changed_stars)),
                         want);
    }
  }
}

// The rows the gradient's pass keeps for the removals are the structure's VV, every vertex,
// whichever consumer read which block.
TEST(TopologicalSimplification, GradientPassKeepsEveryVertexsNeighbours) {
  const Input in = Noisy(9, 31, /*block_size=*/20);
  auto explicit_structure = OkValue(ExplicitStructure::Build(in.topo, {}));
  auto want = explicit_structure->NewReader();
  const auto expect_rows = [&](const VertexNeighbors& kept) {
    std::vector<SimplexId> decoded;
    for (SimplexId v = 0; v < in.topo->num_vertices(); ++v) {
      const auto row = kept.vertex_neighbors(v, decoded);
      const auto expected = want.vertex_neighbors(v);
      ASSERT_EQ(std::vector<SimplexId>(row.begin(), row.end()),
                std::vector<SimplexId>(expected.begin(), expected.end()))
          << "vertex " << v;
    }
  };
  for (int consumers : {1, 2, 3}) {
    SCOPED_TRACE(consumers);
    const RunContext context{.consumers = consumers};
    CompactStructure compact(in.topo, {.cache_ratio = 0.05, .consumers = consumers});
    VertexNeighbors from_compact(*in.topo);
    ASSERT_TRUE(
        RunDiscreteGradient(compact, in.order, context, GradientArrays::kPersistence, &from_compact)
            .ok());
    expect_rows(from_compact);
    auto actopo = OkValue(ActopoStructure::Create(
        in.topo, {.consumers = consumers, .producers = 2, .buffer_ratio = 0.05}));
    VertexNeighbors from_actopo(*in.topo);
    ASSERT_TRUE(
        RunDiscreteGradient(*actopo, in.order, context, GradientArrays::kAll, &from_actopo).ok());
    expect_rows(from_actopo);
  }
}

// Neighbours numbered far from their vertex (the lattice's x-slices alternate between two blocks,
// so every x-neighbour is about half the mesh away) are kept whole, the others as differences.
TEST(TopologicalSimplification, KeptNeighboursFarInIdDecodeWhole) {
  Mesh mesh = testing::Lattice(41, 41, 41);  // 68,921 vertices: x-neighbours 34k apart
  auto topo = OkValue(Topology::Build(mesh, *LabelBlocks(testing::SliceLabels(mesh, 2))));
  ASSERT_EQ(topo->num_blocks(), 2);
  auto explicit_structure = OkValue(ExplicitStructure::Build(topo, {}));
  auto want = explicit_structure->NewReader();
  VertexNeighbors kept(*topo);
  for (int32_t b = 0; b < topo->num_blocks(); ++b) kept.FillBlock(b, want);
  std::vector<SimplexId> decoded;
  int64_t far = 0;
  for (SimplexId v = 0; v < topo->num_vertices(); ++v) {
    const auto row = kept.vertex_neighbors(v, decoded);
    const auto expected = want.vertex_neighbors(v);
    ASSERT_EQ(std::vector<SimplexId>(row.begin(), row.end()),
              std::vector<SimplexId>(expected.begin(), expected.end()))
        << "vertex " << v;
    for (SimplexId u : expected) far += std::abs(u - v) > 32767;
  }
  EXPECT_GT(far, 100000);  // the far path is taken, not only the differences
}

// The update's contract holds for any set of moved vertices, not only LTS's (whose neighbours
// rarely change side): vertices moved to random ranks, the others keeping their order.
TEST(TopologicalSimplification, UpdatedGradientFollowsAnyReordering) {
  const Input in = Noisy(9, 23, /*block_size=*/30);
  auto structure = OkValue(ExplicitStructure::Build(in.topo, {}));
  const auto before = OkValue(RunDiscreteGradient(*structure, in.order, {}, GradientArrays::kAll));
  std::mt19937_64 rng(7);
  for (double share : {0.01, 0.05, 0.3}) {
    SCOPED_TRACE(share);
    const SimplexId n = in.topo->num_vertices();
    std::vector<SimplexId> by_rank(n), moved, rest;
    for (SimplexId v = 0; v < n; ++v) by_rank[in.order[v]] = v;
    std::bernoulli_distribution pick(share);
    for (SimplexId v : by_rank) (pick(rng) ? moved : rest).push_back(v);
    for (SimplexId v : moved) {
      rest.insert(rest.begin() + std::uniform_int_distribution<size_t>(0, rest.size())(rng), v);
    }
    std::vector<SimplexId> order(n);
    for (SimplexId r = 0; r < n; ++r) order[rest[r]] = r;
    std::sort(moved.begin(), moved.end());
    const auto want = OkValue(RunDiscreteGradient(*structure, order, {}, GradientArrays::kAll));
    ExpectSameGradient(OkValue(UpdateDiscreteGradient(*structure, before, order, moved, {})), want);
    CompactStructure compact(in.topo, {.cache_ratio = 0.05, .consumers = 2});
    ExpectSameGradient(
        OkValue(UpdateDiscreteGradient(compact, before, order, moved, {.consumers = 2})), want);
  }
}

TEST(TopologicalSimplification, RejectsBadThresholds) {
  for (const SimplificationOptions& bad :
       {SimplificationOptions{.threshold = -1}, SimplificationOptions{.threshold = NAN},
        SimplificationOptions{.threshold = 1.5, .relative = true}}) {
    const absl::Status s = ValidateSimplificationOptions(bad);
    EXPECT_EQ(s.code(), absl::StatusCode::kInvalidArgument);
    EXPECT_NE(s.message().find("threshold"), std::string::npos) << s;
  }
  EXPECT_TRUE(ValidateSimplificationOptions({.threshold = 3}).ok());
}

}  // namespace
}  // namespace actopo
