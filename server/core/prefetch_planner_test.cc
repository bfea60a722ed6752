// PrefetchPlanner and TransitionModel: which (block, relation) pairs each prefetch mode and
// precompute scope plans, in which order, and where the next re-plan triggers.
#include "server/core/prefetch_planner.h"

#include <algorithm>

#include "gmock/gmock.h"
#include "gtest/gtest.h"
#include "server/core/partition.h"
#include "server/core/testing/test_meshes.h"

namespace actopo {
namespace {

using ::testing::ElementsAre;
using ::testing::ElementsAreArray;

std::shared_ptr<const Topology> Blocks() {
  const Mesh mesh = testing::Lattice(6, 6, 6);
  auto topo = Topology::Build(mesh, OctreeBlocks(mesh.points, {.bucket_capacity = 8}));
  EXPECT_TRUE(topo.ok()) << topo.status();
  return *std::move(topo);
}

bool All(int32_t, Relation) { return true; }

std::vector<int32_t> PlannedBlocks(const PrefetchPlanner::Plan& plan) {
  std::vector<int32_t> out;
  for (const BlockTask& t : plan.tasks) {
    if (out.empty() || out.back() != t.block) out.push_back(t.block);
  }
  return out;
}

class PrefetchPlannerTest : public ::testing::Test {
 protected:
  void SetUp() override { ASSERT_GE(topo_->num_blocks(), 20); }
  std::shared_ptr<const Topology> topo_ = Blocks();
  PrefetchPlanner::Plan plan_;
};

TEST_F(PrefetchPlannerTest, LinearPlansTheNextBlocksAndTriggersHalfWay) {
  PrefetchPlanner planner(*topo_, {.prefetch = Prefetch::kLinear, .window = 4});
  planner.Make({.block = 5, .relation = Relation::kVT}, {}, All, plan_);
  ASSERT_EQ(plan_.tasks.size(), 4u);
  for (int i = 0; i < 4; ++i) {
    EXPECT_EQ(plan_.tasks[i].block, 6 + i);
    EXPECT_EQ(plan_.tasks[i].relation, Relation::kVT);
  }
  EXPECT_EQ(plan_.trigger_block, 8);
}

TEST_F(PrefetchPlannerTest, LinearStopsAtTheLastBlock) {
  PrefetchPlanner planner(*topo_, {.prefetch = Prefetch::kLinear, .window = 4});
  const int32_t last = topo_->num_blocks() - 1;
  planner.Make({.block = last - 2, .relation = Relation::kVE}, {}, All, plan_);
  EXPECT_THAT(PlannedBlocks(plan_), ElementsAre(last - 1, last));
  EXPECT_EQ(plan_.trigger_block, last);
  planner.Make({.block = last, .relation = Relation::kVE}, {}, All, plan_);
  EXPECT_TRUE(plan_.tasks.empty());
  EXPECT_EQ(plan_.trigger_block, -1);
}

TEST_F(PrefetchPlannerTest, SpatialPlansNeighboursAscendingUpToTheWindow) {
  // A block with more neighbours than the window.
  int32_t b = 0;
  while (topo_->block_neighbors(b).size() < 4) ++b;
  const auto neighbours = topo_->block_neighbors(b);
  ASSERT_TRUE(std::is_sorted(neighbours.begin(), neighbours.end()));
  PrefetchPlanner planner(*topo_, {.prefetch = Prefetch::kSpatial, .window = 3});
  planner.Make({.block = b, .relation = Relation::kTT}, {}, All, plan_);
  EXPECT_THAT(PlannedBlocks(plan_), ElementsAreArray(neighbours.subspan(0, 3)));
  EXPECT_EQ(plan_.trigger_block, neighbours[0]);
}

TEST_F(PrefetchPlannerTest, AdaptivePlansPredictionsFirstThenNeighbours) {
  int32_t b = 0;
  while (topo_->block_neighbors(b).size() < 3) ++b;
  const auto neighbours = topo_->block_neighbors(b);
  const int32_t far = topo_->num_blocks() - 1;
  ASSERT_EQ(std::count(neighbours.begin(), neighbours.end(), far), 0) << "pick another block";
  PrefetchPlanner planner(*topo_, {.prefetch = Prefetch::kAdaptive, .window = 3});
  // The prediction comes first even when it is no neighbour; duplicates and b itself are
  // skipped.
  const std::vector<int32_t> predicted = {far, b, far, neighbours[1]};
  planner.Make({.block = b, .relation = Relation::kVE}, predicted, All, plan_);
  EXPECT_THAT(PlannedBlocks(plan_), ElementsAre(far, neighbours[1], neighbours[0]));
  EXPECT_EQ(plan_.trigger_block, far);
}

TEST_F(PrefetchPlannerTest, DeclaredPlansTheWholeSetOnTheMovedToBlockToo) {
  PrefetchPlanner planner(*topo_, {.prefetch = Prefetch::kLinear,
                                   .precompute = Precompute::kDeclared,
                                   .declared = {Relation::kTV, Relation::kVT, Relation::kVE},
                                   .window = 2});
  planner.Make({.block = 3, .relation = Relation::kVT}, {}, All, plan_);
  // Static relations (TV) are never planned; declared relations in relation order.
  std::vector<std::pair<int32_t, Relation>> got;
  for (const BlockTask& t : plan_.tasks) got.emplace_back(t.block, t.relation);
  EXPECT_THAT(got, ElementsAre(std::pair(3, Relation::kVE), std::pair(3, Relation::kVT),
                               std::pair(4, Relation::kVE), std::pair(4, Relation::kVT),
                               std::pair(5, Relation::kVE), std::pair(5, Relation::kVT)));
}

TEST_F(PrefetchPlannerTest, OnlyThePlannedRelationsOfADeclaredSetSayWhereTheSweepGoes) {
  // Critical points: VT swept block by block, VB read wherever a boundary vertex's neighbours
  // lie. A miss on VB must not move the plan there.
  PrefetchPlanner declared(
      *topo_, {.precompute = Precompute::kDeclared, .declared = {Relation::kVT, Relation::kTV}});
  EXPECT_TRUE(declared.Follows(Relation::kVT));
  EXPECT_FALSE(declared.Follows(Relation::kVB));
  EXPECT_FALSE(declared.Follows(Relation::kTV)) << "static: never planned";
  // Under kRequested the plan is of whatever relation was read, so every read guides it.
  PrefetchPlanner requested(*topo_,
                            {.precompute = Precompute::kRequested, .declared = {Relation::kVT}});
  EXPECT_TRUE(requested.Follows(Relation::kVB));
}

TEST_F(PrefetchPlannerTest, LeavesOutWhatIsNotNeeded) {
  PrefetchPlanner planner(*topo_, {.prefetch = Prefetch::kLinear, .window = 4});
  planner.Make(
      {.block = 0, .relation = Relation::kVT}, {}, [](int32_t b, Relation) { return b % 2 == 0; },
      plan_);
  EXPECT_THAT(PlannedBlocks(plan_), ElementsAre(2, 4));
  // The trigger still follows the window, needed or not: the consumer passes those blocks.
  EXPECT_EQ(plan_.trigger_block, 3);
}

TEST(TransitionModel, PredictsTheStrongestSuccessorsThenTheirChain) {
  TransitionModel model(10);
  for (int i = 0; i < 3; ++i) model.Learn(0, 4);
  model.Learn(0, 2);
  model.Learn(4, 7);
  model.Learn(4, 7);
  model.Learn(7, 9);
  model.Learn(-1, 3);  // from nowhere: nothing learnt
  model.Learn(5, 5);   // staying: nothing learnt
  std::vector<int32_t> out;
  model.Predict(0, 8, out);
  EXPECT_THAT(out, ElementsAre(4, 2, 7, 9));
  model.Predict(0, 2, out);
  EXPECT_THAT(out, ElementsAre(4, 2));
  model.Predict(3, 8, out);
  EXPECT_TRUE(out.empty());
  model.Predict(5, 8, out);
  EXPECT_TRUE(out.empty());
}

TEST(TransitionModel, ANewSuccessorReplacesTheWeakestAndInheritsItsCount) {
  TransitionModel model(10);
  for (int32_t to : {1, 2, 3, 4}) {
    for (int i = 0; i < to; ++i) model.Learn(0, to);  // counts 1, 2, 3, 4
  }
  model.Learn(0, 8);  // replaces block 1 (count 1) and counts 2
  std::vector<int32_t> out;
  model.Predict(0, 4, out);
  EXPECT_THAT(out, ElementsAre(4, 3, ::testing::AnyOf(2, 8), ::testing::AnyOf(2, 8)));
  EXPECT_EQ(std::count(out.begin(), out.end(), 1), 0);
}

}  // namespace
}  // namespace actopo
