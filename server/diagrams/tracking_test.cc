#include "server/diagrams/tracking.h"

#include <random>
#include <set>

#include "gtest/gtest.h"

namespace actopo::diagrams {
namespace {

// A diagram of type-0 points, pair i being points[i].
Diagram Type0(std::vector<Point> points) {
  Diagram d;
  for (size_t i = 0; i < points.size(); ++i) d.point_pairs[0].push_back(int32_t(i));
  d.points[0] = std::move(points);
  return d;
}

TEST(TrackPairs, FollowsAPairThroughTheStepsAndEndsAtTheDiagonal) {
  const std::vector<Diagram> steps = {
      Type0({{0, 4}, {1, 1.2}}),    // the small pair goes to the diagonal
      Type0({{5, 9}, {0.2, 4.1}}),  // a pair is born
      Type0({{0.3, 4.3}, {5.1, 9}, {7, 7.1}}),
  };
  const Tracking tracking = TrackPairs(steps, {.p = 2});
  ASSERT_EQ(tracking.trajectories.size(), 2u);
  const Trajectory& first = tracking.trajectories[0];
  EXPECT_EQ(first.first_step, 0);
  EXPECT_EQ(first.pairs, (std::vector<int32_t>{0, 1, 0}));
  ASSERT_EQ(first.costs.size(), 2u);
  EXPECT_DOUBLE_EQ(first.costs[0], 0.2);    // max(|0 - 0.2|, |4 - 4.1|)
  EXPECT_NEAR(first.costs[1], 0.2, 1e-15);  // max(|0.2 - 0.3|, |4.1 - 4.3|), rounded
  const Trajectory& second = tracking.trajectories[1];
  EXPECT_EQ(second.first_step, 1);
  EXPECT_EQ(second.pairs, (std::vector<int32_t>{0, 1}));
  ASSERT_EQ(tracking.steps.size(), 2u);
  EXPECT_DOUBLE_EQ(tracking.steps[0].wasserstein,
                   ComputeDistance(steps[0], steps[1], {.p = 2}).wasserstein);
}

TEST(TrackPairs, LinksAreTheStepsOptimalMatchingsAndEveryPairIsInOneTrajectory) {
  std::mt19937 rng(17);
  std::uniform_real_distribution<double> value(0, 10), jitter(-0.3, 0.3), unit(0, 1);
  std::vector<Diagram> steps;
  std::vector<Point> base;
  for (int k = 0; k < 40; ++k) {
    const double b = value(rng);
    base.push_back({b, b + (unit(rng) < 0.7 ? 0.4 : 4) * unit(rng)});
  }
  for (int t = 0; t < 6; ++t) {
    Diagram d;
    for (int type = 0; type < kPairTypes; ++type) {
      for (const Point& p : base) {
        if (unit(rng) < 0.1) continue;  // pairs come and go
        const double b = p.birth + jitter(rng);
        d.points[type].push_back({b, std::max(b, p.death + jitter(rng))});
        d.point_pairs[type].push_back(int32_t(d.point_pairs[type].size()) * 3 + type);
      }
    }
    steps.push_back(std::move(d));
  }
  for (const int threads : {1, 2}) {
    const Tracking tracking = TrackPairs(steps, {.p = 2}, threads);
    ASSERT_EQ(tracking.steps.size(), steps.size() - 1);
    std::set<std::tuple<int, int, int>> seen;  // (step, type, pair)
    for (const Trajectory& t : tracking.trajectories) {
      ASSERT_GE(t.pairs.size(), 2u);
      ASSERT_EQ(t.costs.size(), t.pairs.size() - 1);
      for (size_t k = 0; k < t.pairs.size(); ++k) {
        EXPECT_TRUE(seen.insert({t.first_step + int(k), t.type, t.pairs[k]}).second)
            << "a pair in two trajectories";
      }
      for (size_t k = 0; k + 1 < t.pairs.size(); ++k) {
        // The link is a match of that step's optimal matching, at its ground cost.
        const Distance& step = tracking.steps[t.first_step + k];
        bool found = false;
        for (const PairMatch& m : step.matching) {
          found |= m.type == t.type && m.pair_a == t.pairs[k] && m.pair_b == t.pairs[k + 1] &&
                   m.cost == t.costs[k];
        }
        EXPECT_TRUE(found);
      }
    }
    for (size_t s = 0; s + 1 < steps.size(); ++s) {
      EXPECT_NEAR(tracking.steps[s].wasserstein,
                  ComputeDistance(steps[s], steps[s + 1], {.p = 2}).wasserstein, 1e-12);
    }
    EXPECT_GT(tracking.trajectories.size(), 40u);
  }
}

TEST(TrackPairs, OneStepTracksNothing) {
  const std::vector<Diagram> one = {Type0({{0, 1}})};
  const Tracking tracking = TrackPairs(one, {});
  EXPECT_TRUE(tracking.trajectories.empty());
  EXPECT_TRUE(tracking.steps.empty());
}

}  // namespace
}  // namespace actopo::diagrams
