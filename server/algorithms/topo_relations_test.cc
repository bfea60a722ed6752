#include "server/algorithms/topo_relations.h"

#include <atomic>

#include "gtest/gtest.h"
#include "server/core/actopo_structure.h"
#include "server/core/compact_structure.h"
#include "server/core/explicit_structure.h"
#include "server/core/partition.h"
#include "server/core/testing/oracle.h"
#include "server/core/testing/status.h"
#include "server/core/testing/test_meshes.h"

namespace actopo {
namespace {

std::shared_ptr<const Topology> Build(const Mesh& m, int capacity) {
  return OkValue(Topology::Build(m, OctreeBlocks(m.points, {.bucket_capacity = capacity})));
}

TopoRelationsResult RunExplicit(std::shared_ptr<const Topology> topo, int consumers,
                                TopoRelationsOptions options = {}) {
  auto structure = OkValue(ExplicitStructure::Build(topo, {.relations = TopoRelationsDeclared()}));
  return OkValue(RunTopoRelations(*structure, {.consumers = consumers}, options));
}

TEST(TopoRelations, TotalsMatchOracleAndIdentities) {
  const Mesh m = testing::Lattice(7, 6, 5, 21);
  auto topo = Build(m, 20);
  testing::RelationOracle oracle(*topo);
  const TopoRelationsResult r = RunExplicit(topo, 1, {.all = true});
  for (Relation rel : AllRelations()) {
    int64_t expected = 0;
    for (const auto& row : oracle.rows(rel)) expected += row.size();
    EXPECT_EQ(r.totals[Index(rel)], expected) << RelationName(rel);
  }
  const int64_t V = topo->num_vertices(), E = topo->num_edges(), F = topo->num_triangles(),
                T = topo->num_tetrahedra();
  const int64_t Fb = 2 * F - 4 * T;
  auto total = [&](Relation rel) { return r.totals[Index(rel)]; };
  EXPECT_EQ(V - E + F - T, 1);
  EXPECT_EQ(total(Relation::kVT), 4 * T);
  EXPECT_EQ(total(Relation::kVE), 2 * E);
  EXPECT_EQ(total(Relation::kVV), 2 * E);
  EXPECT_EQ(total(Relation::kVF), 3 * F);
  EXPECT_EQ(total(Relation::kET), 6 * T);
  EXPECT_EQ(total(Relation::kEF), 3 * F);
  EXPECT_EQ(total(Relation::kFT), 4 * T);
  EXPECT_EQ(total(Relation::kTT), 2 * (F - Fb));
  EXPECT_EQ(total(Relation::kVL), 4 * T);
  EXPECT_EQ(total(Relation::kFB), F);
}

// By default the sweep reads TTK's 20 relations, the same totals as the full sweep's, and
// leaves the edge and triangle neighbours unread.
TEST(TopoRelations, DefaultSweepsTtksTwentyRelations) {
  auto topo = Build(testing::Lattice(6, 5, 4, 3), 20);
  const TopoRelationsResult ttk = RunExplicit(topo, 2);
  const TopoRelationsResult all = RunExplicit(topo, 2, {.all = true});
  EXPECT_FALSE(ttk.all);
  EXPECT_TRUE(all.all);
  ASSERT_EQ(TopoRelationsSweeps().size(), 20u);
  ASSERT_EQ(TopoRelationsSweeps(true).size(), size_t(kNumRelations));
  for (Relation rel : TopoRelationsSweeps()) {
    EXPECT_NE(rel, Relation::kEE);
    EXPECT_NE(rel, Relation::kFF);
    EXPECT_EQ(ttk.totals[Index(rel)], all.totals[Index(rel)]) << RelationName(rel);
  }
  EXPECT_EQ(ttk.totals[Index(Relation::kEE)], 0);
  EXPECT_EQ(ttk.totals[Index(Relation::kFF)], 0);
  EXPECT_GT(all.totals[Index(Relation::kEE)], 0);
  EXPECT_GT(all.totals[Index(Relation::kFF)], 0);
  EXPECT_NE(ttk.checksum, all.checksum);
}

TEST(TopoRelations, IdenticalAcrossStructuresConsumersAndCacheSizes) {
  for (const Mesh& m :
       {testing::Lattice(8, 7, 6, 2), testing::NonManifold(), testing::TwoComponents()}) {
    auto topo = Build(m, 13);
    // All 22 relations, so the neighbours each structure computes are compared too.
    const TopoRelationsResult reference = RunExplicit(topo, 1, {.all = true});
    EXPECT_NE(reference.checksum, 0u);
    for (int consumers : {1, 2, 3}) {
      const TopoRelationsResult e = RunExplicit(topo, consumers, {.all = true});
      EXPECT_EQ(e.totals, reference.totals);
      EXPECT_EQ(e.checksum, reference.checksum) << "explicit, consumers " << consumers;
      for (double ratio : {0.0, 0.2, 1.0}) {
        CompactStructure compact(topo, {.cache_ratio = ratio, .consumers = consumers});
        const TopoRelationsResult c =
            OkValue(RunTopoRelations(compact, {.consumers = consumers}, {.all = true}));
        EXPECT_EQ(c.totals, reference.totals);
        EXPECT_EQ(c.checksum, reference.checksum)
            << "compact, consumers " << consumers << ", ratio " << ratio;
      }
    }
  }
}

TEST(TopoRelations, ChecksumSeesDifferentMeshes) {
  const TopoRelationsResult a = RunExplicit(Build(testing::Lattice(5, 5, 5), 1000), 1);
  const TopoRelationsResult b = RunExplicit(Build(testing::Lattice(5, 5, 6), 1000), 1);
  EXPECT_NE(a.checksum, b.checksum);
}

TEST(TopoRelations, ReportsProgressAndStopsWhenCancelled) {
  auto topo = Build(testing::Lattice(9, 9, 9, 4), 10);
  CompactStructure compact(topo, {});
  std::vector<double> seen;
  RunContext context{.progress = [&](double f) { seen.push_back(f); }};
  ASSERT_TRUE(RunTopoRelations(compact, context).ok());
  ASSERT_FALSE(seen.empty());
  EXPECT_TRUE(std::is_sorted(seen.begin(), seen.end()));
  EXPECT_DOUBLE_EQ(seen.back(), 1.0);

  std::atomic<bool> cancel{false};
  int calls = 0;
  RunContext cancelling{.consumers = 2,
                        .progress =
                            [&](double) {
                              if (++calls == 3) cancel = true;
                            },
                        .cancel = &cancel};
  const auto cancelled = RunTopoRelations(compact, cancelling);
  EXPECT_EQ(cancelled.status().code(), absl::StatusCode::kCancelled);
}

}  // namespace
}  // namespace actopo

namespace actopo {
namespace {

TEST(TopoRelations, ActopoMatchesExplicitInEveryMode) {
  auto topo = Build(testing::Lattice(7, 6, 6, 6), 11);
  const TopoRelationsResult reference = RunExplicit(topo, 1, {.all = true});
  for (Prefetch p : {Prefetch::kLinear, Prefetch::kSpatial, Prefetch::kAdaptive}) {
    for (Precompute q : {Precompute::kRequested, Precompute::kDeclared}) {
      for (int producers : {1, 2, 4}) {
        for (int consumers : {1, 2}) {
          for (double ratio : {0.01, 0.2, 1.0}) {
            auto structure = OkValue(ActopoStructure::Create(topo, {.consumers = consumers,
                                                                    .producers = producers,
                                                                    .buffer_ratio = ratio,
                                                                    .prefetch = p,
                                                                    .precompute = q}));
            const TopoRelationsResult r =
                OkValue(RunTopoRelations(*structure, {.consumers = consumers}, {.all = true}));
            EXPECT_EQ(r.totals, reference.totals);
            EXPECT_EQ(r.checksum, reference.checksum)
                << PrefetchName(p) << " " << PrecomputeName(q) << " P=" << producers
                << " C=" << consumers << " ratio=" << ratio;
            // Bounded buffer: no pin may leak, else blocks could never be evicted.
            for (const EngineStats& s : structure->consumer_stats()) {
              EXPECT_LE(s.buffer_peak_blocks,
                        structure->buffer_capacity_blocks() + 1 + kNumRelations);
            }
          }
        }
      }
    }
  }
}

TEST(TopoRelations, CancelStopsActopoRun) {
  auto topo = Build(testing::Lattice(10, 10, 10, 3), 8);
  auto structure = OkValue(ActopoStructure::Create(topo, {.consumers = 2, .producers = 2}));
  std::atomic<bool> cancel{false};
  int calls = 0;
  RunContext context{.consumers = 2,
                     .progress =
                         [&](double) {
                           if (++calls == 2) {
                             cancel = true;
                             structure->Shutdown();  // what a session does on cancellation
                           }
                         },
                     .cancel = &cancel};
  EXPECT_EQ(RunTopoRelations(*structure, context).status().code(), absl::StatusCode::kCancelled);
}

}  // namespace
}  // namespace actopo
