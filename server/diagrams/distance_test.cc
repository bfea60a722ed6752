#include "server/diagrams/distance.h"

#include <cmath>
#include <limits>
#include <random>

#include "gtest/gtest.h"

namespace actopo::diagrams {
namespace {

PersistencePair Finite(int type, double birth, double death) {
  return {.type = int8_t(type),
          .birth_cell = 0,
          .death_cell = 0,
          .birth_value = birth,
          .death_value = death};
}
PersistencePair Essential(int type, double birth) {
  return {.type = int8_t(type), .birth_cell = 0, .death_cell = -1, .birth_value = birth};
}

// A random diagram of every type, with one essential pair of type 0.
PersistenceDiagramResult RandomResult(std::mt19937& rng, int per_type) {
  std::uniform_real_distribution<double> value(0, 10), unit(0, 1);
  PersistenceDiagramResult r;
  r.pairs.push_back(Essential(0, value(rng)));
  for (int type = 0; type < 3; ++type) {
    for (int k = 0; k < per_type; ++k) {
      const double birth = value(rng);
      r.pairs.push_back(Finite(type, birth, birth + (unit(rng) < 0.8 ? 0.3 : 4) * unit(rng)));
    }
  }
  return r;
}

TEST(ToDiagram, SplitsByTypeKeepsPairIndicesAndDropsPairsBelowTheThreshold) {
  PersistenceDiagramResult r;
  r.pairs = {Finite(0, 0, 1), Essential(0, -1), Finite(1, 2, 2.25), Finite(2, 3, 7),
             Finite(0, 5, 5.5)};
  const Diagram all = ToDiagram(r);
  EXPECT_EQ(all.size(), 5);
  ASSERT_EQ(all.points[0].size(), 2u);
  EXPECT_EQ(all.point_pairs[0], (std::vector<int32_t>{0, 4}));
  EXPECT_EQ(all.essential[0], (std::vector<double>{-1}));
  EXPECT_EQ(all.essential_pairs[0], (std::vector<int32_t>{1}));
  EXPECT_EQ(all.point_pairs[2], (std::vector<int32_t>{3}));
  // At 0.5: persistence 0.25 goes, 0.5 stays (at least the threshold), essential pairs stay.
  const Diagram kept = ToDiagram(r, 0.5);
  EXPECT_EQ(kept.point_pairs[0], (std::vector<int32_t>{0, 4}));
  EXPECT_TRUE(kept.points[1].empty());
  EXPECT_EQ(kept.essential[0].size(), 1u);
}

TEST(ComputeDistance, CombinesTheTypesAndIsSymmetric) {
  std::mt19937 rng(3);
  const Diagram x = ToDiagram(RandomResult(rng, 30)), y = ToDiagram(RandomResult(rng, 40));
  for (const double p : {1.0, 2.0, 4.0}) {
    const Distance d = ComputeDistance(x, y, {.p = p});
    double sum = 0, largest = 0;
    for (int t = 0; t < kPairTypes; ++t) {
      EXPECT_DOUBLE_EQ(d.wasserstein_by_type[t],
                       WassersteinMatching(x.points[t], y.points[t], p).value);
      EXPECT_DOUBLE_EQ(d.bottleneck_by_type[t], BottleneckMatching(x.points[t], y.points[t]).value);
      sum += std::pow(d.wasserstein_by_type[t], p);
      largest = std::max(largest, d.bottleneck_by_type[t]);
    }
    EXPECT_NEAR(d.wasserstein, std::pow(sum, 1 / p), 1e-12 * d.wasserstein);
    EXPECT_EQ(d.bottleneck, largest);
    const Distance back = ComputeDistance(y, x, {.p = p});
    EXPECT_NEAR(back.wasserstein, d.wasserstein, 1e-12 * d.wasserstein);
    EXPECT_EQ(back.bottleneck, d.bottleneck);
    // The bottleneck is at most any Wasserstein-p of the same pair of diagrams.
    EXPECT_LE(d.bottleneck, d.wasserstein * (1 + 1e-12));
  }
}

TEST(ComputeDistance, MatchingNamesPairsOfBothDiagrams) {
  std::mt19937 rng(5);
  const PersistenceDiagramResult rx = RandomResult(rng, 10), ry = RandomResult(rng, 12);
  const Diagram x = ToDiagram(rx), y = ToDiagram(ry);
  const Distance d = ComputeDistance(x, y, {.p = 2, .essential = true, .matching = true});
  std::vector<int> seen_x(rx.pairs.size()), seen_y(ry.pairs.size());
  double sum = 0;
  for (const PairMatch& m : d.matching) {
    if (m.pair_a >= 0) {
      ++seen_x[m.pair_a];
      EXPECT_EQ(rx.pairs[m.pair_a].type, m.type);
    }
    if (m.pair_b >= 0) {
      ++seen_y[m.pair_b];
      EXPECT_EQ(ry.pairs[m.pair_b].type, m.type);
    }
    sum += m.cost * m.cost;
  }
  for (int count : seen_x) EXPECT_EQ(count, 1);
  for (int count : seen_y) EXPECT_EQ(count, 1);
  EXPECT_NEAR(std::sqrt(sum), d.wasserstein, 1e-12 * d.wasserstein);
}

TEST(ComputeDistance, EssentialPairsMatchByBirthOrMakeTheDistanceInfinite) {
  PersistenceDiagramResult rx, ry;
  rx.pairs = {Essential(0, 0), Essential(0, 3), Finite(1, 1, 2)};
  ry.pairs = {Essential(0, 4), Essential(0, 0.5), Finite(1, 1, 2)};
  const Diagram x = ToDiagram(rx), y = ToDiagram(ry);
  // Left out by default: only the equal finite pairs count.
  EXPECT_EQ(ComputeDistance(x, y, {}).wasserstein, 0);
  // Births sorted: 0 with 0.5, 3 with 4: W2 = sqrt(0.25 + 1), bottleneck 1.
  const Distance d = ComputeDistance(x, y, {.essential = true});
  EXPECT_DOUBLE_EQ(d.wasserstein, std::sqrt(1.25));
  EXPECT_DOUBLE_EQ(d.bottleneck, 1);
  ry.pairs.push_back(Essential(0, 9));
  const Distance unequal = ComputeDistance(x, ToDiagram(ry), {.essential = true});
  EXPECT_TRUE(std::isinf(unequal.wasserstein));
  EXPECT_TRUE(std::isinf(unequal.bottleneck));
}

TEST(ComputeDistanceMatrix, EqualsEachPairsDistanceOnAnyThreadCount) {
  std::mt19937 rng(9);
  std::vector<Diagram> diagrams;
  for (int k = 0; k < 6; ++k) diagrams.push_back(ToDiagram(RandomResult(rng, 5 + 6 * k)));
  for (const int threads : {1, 2, 3}) {
    int64_t last = 0, calls = 0;
    const DistanceMatrix m = ComputeDistanceMatrix(
        diagrams, {.p = 2}, {.threads = threads, .progress = [&](int64_t done, int64_t total) {
                               EXPECT_EQ(total, 15);
                               last = std::max(last, done);
                               ++calls;
                             }});
    EXPECT_EQ(last, 15);
    EXPECT_EQ(calls, 15);
    ASSERT_EQ(m.size, 6);
    for (int i = 0; i < 6; ++i) {
      EXPECT_EQ(m.at(m.wasserstein, i, i), 0);
      for (int j = 0; j < 6; ++j) {
        if (i == j) continue;
        const Distance d = ComputeDistance(diagrams[i], diagrams[j], {.p = 2});
        EXPECT_NEAR(m.at(m.wasserstein, i, j), d.wasserstein, 1e-12 * d.wasserstein);
        EXPECT_EQ(m.at(m.bottleneck, i, j), d.bottleneck);
        EXPECT_EQ(m.at(m.wasserstein, i, j), m.at(m.wasserstein, j, i));
      }
    }
  }
}

TEST(ComputeDistanceMatrix, StopsWhenAsked) {
  std::mt19937 rng(1);
  std::vector<Diagram> diagrams;
  for (int k = 0; k < 4; ++k) diagrams.push_back(ToDiagram(RandomResult(rng, 10)));
  int64_t calls = 0;
  ComputeDistanceMatrix(
      diagrams, {},
      {.progress = [&](int64_t, int64_t) { ++calls; }, .stopped = [&] { return calls >= 2; }});
  EXPECT_EQ(calls, 2);
}

TEST(ValidateDistanceOptions, NamesTheOrder) {
  EXPECT_TRUE(ValidateDistanceOptions({.p = 1}).ok());
  for (const double p : {0.5, -2.0, std::numeric_limits<double>::infinity(),
                         std::numeric_limits<double>::quiet_NaN()}) {
    const absl::Status s = ValidateDistanceOptions({.p = p});
    EXPECT_EQ(s.code(), absl::StatusCode::kInvalidArgument);
    EXPECT_EQ(s.message().substr(0, 3), "p: ") << s.message();
  }
}

}  // namespace
}  // namespace actopo::diagrams
