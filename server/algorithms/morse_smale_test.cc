#include "server/algorithms/morse_smale.h"

#include <algorithm>
#include <random>
#include <set>

#include "gtest/gtest.h"
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
  std::vector<uint8_t> corners;  // InputCorners
};

Input Make(Mesh mesh, int block_size) {
  auto topo =
      OkValue(Topology::Build(mesh, OctreeBlocks(mesh.points, {.bucket_capacity = block_size})));
  auto order = VertexOrder(*topo, mesh.point_fields[0].values);
  auto corners = OkValue(InputCorners(*topo, mesh.tetrahedra));
  return {std::move(mesh), topo, std::move(order), std::move(corners)};
}

// A cell's sorted internal vertex ids.
std::vector<SimplexId> CellVertices(const Topology& topo, Cell c) {
  switch (c.dim) {
    case 0: return {c.id};
    case 1: {
      const auto v = topo.edge(c.id);
      return {v.begin(), v.end()};
    }
    case 2: {
      const auto v = topo.triangle(c.id);
      return {v.begin(), v.end()};
    }
    default: {
      const auto v = topo.tetrahedron(c.id);
      return {v.begin(), v.end()};
    }
  }
}

void ExpectInvariants(const MorseSmaleResult& r, const Topology& topo) {
  const SimplexId nv = topo.num_vertices();
  // Two descending separatrices per 1-saddle, each from the saddle to a minimum.
  EXPECT_EQ(r.CountSeparatrices(SeparatrixType::kDescending), 2 * r.gradient.critical_cells[1]);
  // At most two ascending separatrices per 2-saddle in a manifold mesh.
  EXPECT_LE(r.CountSeparatrices(SeparatrixType::kAscending), 2 * r.gradient.critical_cells[2]);
  for (const Separatrix& s : r.separatrices) {
    ASSERT_FALSE(s.path.empty());
    EXPECT_EQ(s.path.front(), s.source.id);
    EXPECT_EQ(s.cell(s.path.size() - 1).dim, s.destination.dim);
    EXPECT_EQ(s.path.back(), s.destination.id);
    if (s.type == SeparatrixType::kDescending) {
      EXPECT_EQ(s.destination.dim, 0);
      EXPECT_TRUE(std::binary_search(r.gradient.critical[0].begin(), r.gradient.critical[0].end(),
                                     s.destination.id));
    }
    if (s.type == SeparatrixType::kAscending) {
      EXPECT_EQ(s.destination.dim, 3);
      EXPECT_TRUE(std::binary_search(r.gradient.critical[3].begin(), r.gradient.critical[3].end(),
                                     s.destination.id));
    }
    for (size_t i = 1; i < s.path.size(); ++i) {  // consecutive cells are faces of each other
      std::vector<SimplexId> lower = CellVertices(topo, s.cell(i - 1));
      std::vector<SimplexId> upper = CellVertices(topo, s.cell(i));
      if (lower.size() > upper.size()) std::swap(lower, upper);
      EXPECT_EQ(lower.size() + 1, upper.size()) << "cell " << i;
      EXPECT_TRUE(std::includes(upper.begin(), upper.end(), lower.begin(), lower.end()))
          << "cell " << i << " of a separatrix from " << int(s.source.dim) << "-cell "
          << s.source.id;
    }
  }
  // Every vertex in exactly one descending region; the minima's manifolds cover the mesh.
  ASSERT_EQ(r.descending.size(), size_t(nv));
  int64_t covered = 0;
  for (int64_t size : r.minimum_sizes) covered += size;
  EXPECT_EQ(covered, nv);
  EXPECT_EQ(int64_t(r.minimum_sizes.size()), r.gradient.critical_cells[0]);
  EXPECT_EQ(MorseSmaleResult::Regions(r.descending), r.gradient.critical_cells[0]);
  for (SimplexId l : r.descending) {
    EXPECT_GE(l, 0);
    EXPECT_LT(l, r.gradient.critical_cells[0]);
  }
  for (SimplexId l : r.ascending) EXPECT_LT(l, r.gradient.critical_cells[3]);
  // Morse-Smale labels are dense 0..R-1.
  const int64_t regions = MorseSmaleResult::Regions(r.morse_smale);
  for (SimplexId l : r.morse_smale) {
    EXPECT_GE(l, 0);
    EXPECT_LT(l, regions);
  }
}

TEST(MorseSmaleResult, RegionsCountsDistinctLabelsDenseOrSparse) {
  EXPECT_EQ(MorseSmaleResult::Regions({}), 0);
  const std::vector<SimplexId> dense = {3, -1, 0, 3, 2, -1, 0};  // -1, 0, 2, 3
  EXPECT_EQ(MorseSmaleResult::Regions(dense), 4);
  // Labels spread far beyond 8 per element: counted by sorting, the same way.
  const std::vector<SimplexId> sparse = {1 << 30, -1, 5, 1 << 30, 7, 5};
  EXPECT_EQ(MorseSmaleResult::Regions(sparse), 4);
  std::mt19937 random(11);
  std::vector<SimplexId> labels(5000);
  for (SimplexId& l : labels) l = SimplexId(random() % 900) - 1;
  std::vector<SimplexId> sorted = labels;
  std::sort(sorted.begin(), sorted.end());
  EXPECT_EQ(MorseSmaleResult::Regions(labels),
            std::unique(sorted.begin(), sorted.end()) - sorted.begin());
}

TEST(MorseSmale, InvariantsAndStructureIndependence) {
  for (Input in : {Make(testing::Lattice(10, 9, 8, 31), 23), Make(testing::TwoComponents(), 9)}) {
    auto explicit_structure = OkValue(ExplicitStructure::Build(in.topo, {}));
    const MorseSmaleResult reference =
        OkValue(RunMorseSmale(*explicit_structure, in.order, in.corners, {}));
    ExpectInvariants(reference, *in.topo);
    EXPECT_GT(reference.gradient.critical_cells[1], 0);  // the field has saddles to trace
    const auto digests = [](const MorseSmaleResult& r) {
      std::string cells;  // every separatrix, cell by cell, in the result's order
      for (const Separatrix& s : r.separatrices) {
        cells += std::to_string(int(s.type)) + ":";
        for (size_t i = 0; i < s.path.size(); ++i) {
          const Cell c = s.cell(i);
          cells += std::to_string(c.dim) + "," + std::to_string(c.id) + " ";
        }
        cells += "\n";
      }
      return std::vector<std::string>{MorseSmaleResult::SegmentationDigest(r.descending),
                                      MorseSmaleResult::SegmentationDigest(r.ascending),
                                      MorseSmaleResult::SegmentationDigest(r.morse_smale), cells};
    };
    const auto expected = digests(reference);
    for (int consumers : {1, 2, 3}) {
      EXPECT_EQ(digests(OkValue(RunMorseSmale(*explicit_structure, in.order, in.corners,
                                              {.consumers = consumers}))),
                expected)
          << consumers << " consumers";
      CompactStructure compact(in.topo, {.cache_ratio = 0.05, .consumers = consumers});
      EXPECT_EQ(
          digests(OkValue(RunMorseSmale(compact, in.order, in.corners, {.consumers = consumers}))),
          expected)
          << consumers << " consumers";
    }
    // A gradient given (a simplification's): the stars are scanned in a pass of their own
    // instead of during the gradient's sweep, to the same result.
    for (int consumers : {1, 2}) {
      CompactStructure compact(in.topo, {.cache_ratio = 0.05, .consumers = consumers});
      auto gradient = OkValue(
          RunDiscreteGradient(*explicit_structure, in.order, {}, GradientArrays::kPersistence));
      EXPECT_EQ(digests(OkValue(RunMorseSmale(compact, in.order, in.corners,
                                              {.consumers = consumers}, std::move(gradient)))),
                expected)
          << consumers << " consumers, gradient given";
    }
    for (Prefetch p : {Prefetch::kLinear, Prefetch::kSpatial, Prefetch::kAdaptive}) {
      auto actopo = OkValue(ActopoStructure::Create(in.topo, {.consumers = 3,
                                                              .producers = 2,
                                                              .buffer_ratio = 0.05,
                                                              .prefetch = p,
                                                              .declared = MorseSmaleDeclared()}));
      EXPECT_EQ(digests(OkValue(RunMorseSmale(*actopo, in.order, in.corners, {.consumers = 3}))),
                expected)
          << PrefetchName(p);
    }
  }
}

// A triangle with three tetrahedra: the gradient's sweep records no links there (AscendingLinks
// holds two tetrahedra per triangle), so the stars are scanned in a pass of their own, which
// takes every tetrahedron of a triangle's star.
TEST(MorseSmale, CrowdedTrianglesTakeTheStarPass) {
  Input in = Make(testing::NonManifold(), 4);
  ASSERT_TRUE(in.topo->has_crowded_triangles());
  auto explicit_structure = OkValue(ExplicitStructure::Build(in.topo, {}));
  const MorseSmaleResult r = OkValue(RunMorseSmale(*explicit_structure, in.order, in.corners, {}));
  EXPECT_EQ(r.descending.size(), size_t(in.topo->num_vertices()));
  EXPECT_EQ(r.CountSeparatrices(SeparatrixType::kDescending), 2 * r.gradient.critical_cells[1]);
  CompactStructure compact(in.topo, {.cache_ratio = 0.05, .consumers = 2});
  const MorseSmaleResult c =
      OkValue(RunMorseSmale(compact, in.order, in.corners, {.consumers = 2}));
  EXPECT_EQ(c.morse_smale, r.morse_smale);
  EXPECT_EQ(c.ascending, r.ascending);
  EXPECT_EQ(c.separatrices.size(), r.separatrices.size());
}

TEST(MorseSmale, DoesNotDependOnTheBlockSize) {
  const Mesh mesh = testing::Lattice(8, 8, 8, 77);
  std::set<std::string> seen;
  for (int block_size : {1, 7, 100, 1000}) {
    Input in = Make(mesh, block_size);
    auto s = OkValue(ExplicitStructure::Build(in.topo, {}));
    const MorseSmaleResult r = OkValue(RunMorseSmale(*s, in.order, in.corners, {}));
    seen.insert(MorseSmaleResult::SegmentationDigest(r.morse_smale) + " " +
                std::to_string(r.CountSeparatrices(SeparatrixType::kSaddleConnector)) + " " +
                std::to_string(r.Segments()));
  }
  EXPECT_EQ(seen.size(), 1u);
}

TEST(MorseSmale, RejectsMismatchedTetrahedra) {
  Input in = Make(testing::SingleTetrahedron(), 10);
  auto s = OkValue(ExplicitStructure::Build(in.topo, {}));
  const std::vector<uint8_t> two = {0, 0};
  EXPECT_EQ(RunMorseSmale(*s, in.order, two, {}).status().code(),
            absl::StatusCode::kInvalidArgument);
  for (const std::vector<SimplexId>& wrong :
       {std::vector<SimplexId>{0, 1, 2}, {0, 1, 2, 2}, {0, 1, 2, 7}, {0, 1, -1, 3}}) {
    const auto corners = InputCorners(*in.topo, wrong);
    EXPECT_EQ(corners.status().code(), absl::StatusCode::kInvalidArgument) << corners.status();
  }
}

// Each byte says where each corner of the sorted tuple was in the tetrahedron as given.
TEST(MorseSmale, InputCornersGiveTheOrderAsGiven) {
  Mesh mesh = testing::Lattice(4, 4, 3, 5);  // shuffled ids: tuples as given are not sorted
  auto topo = OkValue(Topology::Build(mesh, OctreeBlocks(mesh.points, {.bucket_capacity = 9})));
  const std::vector<uint8_t> corners = OkValue(InputCorners(*topo, mesh.tetrahedra));
  ASSERT_EQ(corners.size(), size_t(topo->num_tetrahedra()));
  for (SimplexId t = 0; t < topo->num_tetrahedra(); ++t) {
    const auto sorted = topo->tetrahedron(t);
    const SimplexId* given = &mesh.tetrahedra[4 * size_t(topo->tetrahedron_input_id(t))];
    for (int k = 0; k < 4; ++k) {
      const int p = (corners[t] >> (2 * k)) & 3;
      EXPECT_EQ(topo->vertex_internal_id(given[p]), sorted[k]) << "tetrahedron " << t;
    }
  }
}

TEST(MorseSmale, StopsWhenCancelled) {
  Input in = Make(testing::Lattice(9, 9, 9, 2), 20);
  auto s = OkValue(ExplicitStructure::Build(in.topo, {}));
  std::atomic<bool> cancel{true};
  EXPECT_EQ(RunMorseSmale(*s, in.order, in.corners, {.cancel = &cancel}).status().code(),
            absl::StatusCode::kCancelled);
}

TEST(MorseSmale, StopsOnceItsDeadlinePassed) {
  Input in = Make(testing::Lattice(9, 9, 9, 2), 20);
  auto s = OkValue(ExplicitStructure::Build(in.topo, {}));
  const RunContext context{.deadline = Progress::Clock::now() - std::chrono::milliseconds(1)};
  EXPECT_EQ(RunMorseSmale(*s, in.order, in.corners, context).status().code(),
            absl::StatusCode::kDeadlineExceeded);
  // A deadline still ahead changes nothing.
  const RunContext ahead{.deadline = Progress::Clock::now() + std::chrono::hours(1)};
  EXPECT_TRUE(RunMorseSmale(*s, in.order, in.corners, ahead).ok());
}

}  // namespace
}  // namespace actopo
