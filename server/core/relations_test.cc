// Every relation of every simplex, for both structures and several block sizes, against the
// brute-force oracle.
#include <algorithm>
#include <atomic>
#include <cmath>
#include <thread>

#include "gtest/gtest.h"
#include "server/core/block_relations.h"
#include "server/core/compact_structure.h"
#include "server/core/explicit_structure.h"
#include "server/core/partition.h"
#include "server/core/testing/oracle.h"
#include "server/core/testing/relation_checks.h"
#include "server/core/testing/status.h"
#include "server/core/testing/test_meshes.h"

namespace actopo {
namespace {

struct Case {
  std::string name;
  Mesh mesh;
};

std::vector<Case> Meshes() {
  return {{"single_tetrahedron", testing::SingleTetrahedron()},
          {"lattice", testing::Lattice(6, 5, 5, 42)},
          {"two_components", testing::TwoComponents()},
          {"non_manifold", testing::NonManifold()}};
}

class RelationsTest : public ::testing::TestWithParam<int> {};

TEST_P(RelationsTest, ExplicitMatchesOracle) {
  const int capacity = GetParam();
  for (const Case& c : Meshes()) {
    auto topo = OkValue(
        Topology::Build(c.mesh, OctreeBlocks(c.mesh.points, {.bucket_capacity = capacity})));
    testing::RelationOracle oracle(*topo);
    // Edge and triangle neighbours composed at read time (the default), and stored.
    for (RelationSet relations : {ExplicitStructure::DefaultRelations(), RelationSet::All()}) {
      auto structure = ExplicitStructure::Build(topo, {.relations = relations, .threads = 2});
      ASSERT_TRUE(structure.ok()) << structure.status();
      EXPECT_EQ((*structure)->relations().Contains(Relation::kEE), relations == RelationSet::All());
      auto reader = (*structure)->NewReader();
      const std::string label = c.name + (relations == RelationSet::All() ? " stored" : "");
      EXPECT_EQ(testing::CompareWithOracle(reader, oracle, label), 0);
      testing::CompareRandomAccess(reader, oracle, 11, 300, label);
    }
  }
}

TEST_P(RelationsTest, CompactMatchesOracle) {
  const int capacity = GetParam();
  for (const Case& c : Meshes()) {
    auto topo = OkValue(
        Topology::Build(c.mesh, OctreeBlocks(c.mesh.points, {.bucket_capacity = capacity})));
    testing::RelationOracle oracle(*topo);
    for (double ratio : {0.0, 0.2, 1.0}) {
      CompactStructure structure(topo, {.cache_ratio = ratio});
      auto reader = structure.NewReader();
      const std::string label = c.name + " ratio " + std::to_string(ratio);
      EXPECT_EQ(testing::CompareWithOracle(reader, oracle, label), 0);
      testing::CompareRandomAccess(reader, oracle, 7, 300, label);
      EXPECT_GT(reader.stats().requests, 0);
      EXPECT_EQ(reader.stats().requests, reader.stats().hits + reader.stats().misses);
    }
  }
}

// A topology built without edges and triangles (TopologyOptions::faces, the points freed first)
// answers VV, VT and VB like the oracle of the full one; both structures refuse to need more.
TEST_P(RelationsTest, WithoutFacesVertexRelationsMatchOracle) {
  const int capacity = GetParam();
  for (const Case& c : Meshes()) {
    const std::vector<int32_t> blocks = OctreeBlocks(c.mesh.points, {.bucket_capacity = capacity});
    testing::RelationOracle oracle(*OkValue(Topology::Build(c.mesh, blocks)));
    Mesh no_points = c.mesh;
    no_points.points.clear();
    auto topo = OkValue(Topology::Build(no_points, blocks, {.faces = false}));
    ASSERT_FALSE(topo->has_faces());
    EXPECT_EQ(topo->num_edges(), 0);
    EXPECT_EQ(topo->bytes().edges + topo->bytes().triangles, 0);
    CompactStructure compact(topo, {.cache_ratio = 0.2});
    auto compact_reader = compact.NewReader();
    auto structure = ExplicitStructure::Build(
        topo, {.relations = {Relation::kVV, Relation::kVT, Relation::kVB}});
    ASSERT_TRUE(structure.ok()) << structure.status();
    auto explicit_reader = (*structure)->NewReader();
    for (SimplexId v = 0; v < topo->num_vertices(); ++v) {
      const auto expect = [&](Relation r) { return oracle.rows(r)[v]; };
      const auto as_vector = [](std::span<const SimplexId> row) {
        return std::vector<SimplexId>(row.begin(), row.end());
      };
      const std::string where = c.name + " vertex " + std::to_string(v);
      EXPECT_EQ(as_vector(compact_reader.vertex_neighbors(v)), expect(Relation::kVV)) << where;
      EXPECT_EQ(as_vector(compact_reader.vertex_star(v)), expect(Relation::kVT)) << where;
      EXPECT_EQ(compact_reader.vertex_on_boundary(v), expect(Relation::kVB)[0] != 0) << where;
      EXPECT_EQ(as_vector(explicit_reader.vertex_neighbors(v)), expect(Relation::kVV)) << where;
      EXPECT_EQ(explicit_reader.vertex_on_boundary(v), expect(Relation::kVB)[0] != 0) << where;
    }
    const auto refused = ExplicitStructure::Build(topo, {.relations = {Relation::kVE}});
    EXPECT_EQ(refused.status().code(), absl::StatusCode::kFailedPrecondition);
    EXPECT_NE(refused.status().message().find("vertex_edges"), std::string_view::npos)
        << refused.status();
  }
}

INSTANTIATE_TEST_SUITE_P(BlockSizes, RelationsTest, ::testing::Values(1, 7, 100, 1000));

// A vertex with more than 64 neighbours (VB then counts its link edges by sorting): the centre
// of testing::Bipyramid.
TEST(BlockRelations, ManyNeighboursVertexRelationsMatchOracle) {
  for (bool closed : {true, false}) {
    constexpr int kRing = 80;
    const Mesh m = testing::Bipyramid(kRing, closed);
    for (int capacity : {1, 10, 1000}) {
      const std::vector<int32_t> blocks = OctreeBlocks(m.points, {.bucket_capacity = capacity});
      testing::RelationOracle oracle(*OkValue(Topology::Build(m, blocks)));
      auto topo = OkValue(Topology::Build(m, blocks, {.faces = false}));
      CompactStructure compact(topo, {});
      auto reader = compact.NewReader();
      const SimplexId centre = topo->vertex_internal_id(0);
      const auto vv = reader.vertex_neighbors(centre);
      EXPECT_EQ(std::vector<SimplexId>(vv.begin(), vv.end()), oracle.rows(Relation::kVV)[centre]);
      EXPECT_EQ(vv.size(), size_t(closed ? kRing + 2 : kRing + 1));
      EXPECT_EQ(reader.vertex_on_boundary(centre), !closed) << "capacity " << capacity;
      for (SimplexId v = 0; v < topo->num_vertices(); ++v) {
        EXPECT_EQ(reader.vertex_on_boundary(v), oracle.rows(Relation::kVB)[v][0] != 0);
      }
    }
  }
}

TEST(CompactStructure, CacheIsBoundedAndCounted) {
  const Mesh m = testing::Lattice(8, 8, 8, 3);
  auto topo = OkValue(Topology::Build(m, OctreeBlocks(m.points, {.bucket_capacity = 16})));
  ASSERT_GE(topo->num_blocks(), 20);
  CompactStructure structure(topo, {.cache_ratio = 0.2, .consumers = 2});
  EXPECT_EQ(structure.reader_capacity(), int(0.2 * topo->num_blocks() / 2) + 1);
  {
    auto reader = structure.NewReader();
    int64_t total = 0;
    for (SimplexId v = 0; v < topo->num_vertices(); ++v) total += reader.vertex_star(v).size();
    EXPECT_EQ(total, 4 * int64_t(topo->num_tetrahedra()));
    const AccessStats& s = reader.stats();
    EXPECT_EQ(s.misses, topo->num_blocks());  // a sequential sweep computes each block once
    EXPECT_EQ(s.hits, 0);
    EXPECT_EQ(s.evictions, topo->num_blocks() - structure.reader_capacity());
    EXPECT_GT(structure.memory().relation_bytes, 0);
  }
  // Finished readers hand their counters and memory back.
  EXPECT_EQ(structure.stats().misses, topo->num_blocks());
  EXPECT_EQ(structure.memory().relation_bytes, 0);
  EXPECT_GT(structure.memory().relation_peak_bytes, 0);
}

TEST(CompactStructure, AFinishedBlockLeavesTheCacheAtOnce) {
  const Mesh m = testing::Lattice(8, 8, 8, 3);
  auto topo = OkValue(Topology::Build(m, OctreeBlocks(m.points, {.bucket_capacity = 16})));
  testing::RelationOracle oracle(*topo);
  CompactStructure structure(topo, {.cache_ratio = 1.0, .consumers = 1});
  auto reader = structure.NewReader();
  // A sweep that says when it leaves a block holds one block at a time, though the cache could
  // hold them all.
  int64_t largest = 0;
  for (int32_t b = 0; b < topo->num_blocks(); ++b) {
    ASSERT_EQ(testing::CompareBlockStarsAndEdges(reader, oracle, b), 0);
    largest = std::max(largest, structure.memory().relation_bytes);
    reader.Finished(b);
    EXPECT_EQ(structure.memory().relation_bytes, 0) << "block " << b;
  }
  EXPECT_GT(largest, 0);
  EXPECT_EQ(structure.memory().relation_peak_bytes, largest);
  EXPECT_EQ(reader.stats().evictions, topo->num_blocks());
  // A finished block read again is computed again, and correct; a block not cached is a no-op.
  reader.Finished(0);
  EXPECT_EQ(testing::CompareWithOracle(reader, oracle, "after the sweep"), 0);
}

TEST(CompactStructure, ConcurrentReadersAgree) {
  const Mesh m = testing::Lattice(7, 6, 6, 5);
  auto topo = OkValue(Topology::Build(m, OctreeBlocks(m.points, {.bucket_capacity = 7})));
  testing::RelationOracle oracle(*topo);
  CompactStructure structure(topo, {.cache_ratio = 0.1, .consumers = 3});
  std::vector<std::thread> threads;
  for (int c = 0; c < 3; ++c) {
    threads.emplace_back([&, c] {
      auto reader = structure.NewReader();
      testing::CompareRandomAccess(reader, oracle, 100 + c, 200, "consumer " + std::to_string(c));
    });
  }
  for (auto& t : threads) t.join();
  EXPECT_GT(structure.stats().requests, 0);
}

TEST(BlockRelations, RowsCoverExactlyTheBlocksSimplices) {
  const Mesh m = testing::Lattice(5, 5, 5, 8);
  auto topo = OkValue(Topology::Build(m, OctreeBlocks(m.points, {.bucket_capacity = 10})));
  BlockScratch scratch;
  for (Relation r : AllRelations()) {
    if (IsStatic(r)) continue;
    for (int32_t b = 0; b < topo->num_blocks(); ++b) {
      const RelationBlock rb = ComputeBlockRelation(*topo, r, b, scratch);
      EXPECT_EQ(rb.first, topo->block_begin(SourceDimension(r), b));
      EXPECT_EQ(rb.count, topo->block_size(SourceDimension(r), b));
      EXPECT_EQ(rb.stride, FixedSize(r));
      if (rb.stride == 0) {
        EXPECT_EQ(rb.offsets.size(), size_t(rb.count) + 1);
      } else {
        EXPECT_EQ(rb.values.size(), size_t(rb.count) * rb.stride);
      }
    }
  }
}

}  // namespace
}  // namespace actopo

namespace actopo {
namespace {

TEST(ExplicitProgress, ReportsPerRelationAndStopsBetweenThem) {
  const Mesh m = testing::Lattice(8, 7, 6, 3);
  auto topo = OkValue(Topology::Build(m, OctreeBlocks(m.points, {.bucket_capacity = 20})));
  std::vector<double> fractions;
  std::atomic<bool> cancel{false};
  const Progress progress({.cancel = &cancel, .report = [&](std::string_view phase, double f) {
                             EXPECT_EQ(phase, "precompute");
                             fractions.push_back(f);
                             if (fractions.size() == 3) cancel = true;
                           }});
  const auto stopped = ExplicitStructure::Build(topo, {.threads = 2}, progress);
  EXPECT_EQ(stopped.status().code(), absl::StatusCode::kCancelled);
  EXPECT_EQ(fractions.size(), 3u);

  fractions.clear();
  cancel = false;
  const Progress watching({.report = [&](std::string_view, double f) { fractions.push_back(f); }});
  ASSERT_TRUE(ExplicitStructure::Build(topo, {.threads = 2}, watching).ok());
  EXPECT_EQ(fractions.back(), 1);
  EXPECT_TRUE(std::is_sorted(fractions.begin(), fractions.end()));
  EXPECT_GT(fractions.size(), 5u);  // one per computed relation, and the end
}

}  // namespace
}  // namespace actopo
