#include "server/diagrams/matching.h"

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <random>
#include <vector>

#include "gtest/gtest.h"

namespace actopo::diagrams {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

// Random diagrams: births in [0, 10), persistences mostly small (crowding the diagonal, as real
// diagrams do) and a few large; values on a coarse grid when `ties`, so that costs tie.
std::vector<Point> RandomDiagram(int count, std::mt19937& rng, bool ties = false) {
  std::uniform_real_distribution<double> birth(0, 10), unit(0, 1);
  std::vector<Point> points;
  for (int k = 0; k < count; ++k) {
    double b = birth(rng);
    double persistence = unit(rng) < 0.8 ? 0.5 * unit(rng) : 5 * unit(rng);
    if (ties) {
      b = std::round(b * 2) / 2;
      persistence = std::round(persistence * 4) / 4;
    }
    points.push_back({b, b + persistence});
  }
  return points;
}

// The oracle by exhaustion: every partial matching of a into b, the rest to the diagonal.
// `combine` folds a cost into the running total (sum of powers, or max).
template <class Combine>
double Exhaustive(const std::vector<Point>& a, const std::vector<Point>& b, Combine combine,
                  size_t i, std::vector<bool>& used, double acc) {
  if (i == a.size()) {
    for (size_t j = 0; j < b.size(); ++j) {
      if (!used[j]) acc = combine(acc, DiagonalCost(b[j]));
    }
    return acc;
  }
  double best = Exhaustive(a, b, combine, i + 1, used, combine(acc, DiagonalCost(a[i])));
  for (size_t j = 0; j < b.size(); ++j) {
    if (used[j]) continue;
    used[j] = true;
    best = std::min(best,
                    Exhaustive(a, b, combine, i + 1, used, combine(acc, GroundCost(a[i], b[j]))));
    used[j] = false;
  }
  return best;
}

double ExhaustiveWasserstein(const std::vector<Point>& a, const std::vector<Point>& b, double p) {
  std::vector<bool> used(b.size());
  const double sum = Exhaustive(
      a, b, [p](double acc, double c) { return acc + std::pow(c, p); }, 0, used, 0);
  return std::pow(sum, 1 / p);
}

double ExhaustiveBottleneck(const std::vector<Point>& a, const std::vector<Point>& b) {
  std::vector<bool> used(b.size());
  return Exhaustive(
      a, b, [](double acc, double c) { return std::max(acc, c); }, 0, used, 0);
}

// The oracle for larger diagrams: the dense (n + m) x (n + m) assignment problem (every a_i
// against every b_j and its own diagonal copy only; diagonal copies against each other for
// free), solved by the textbook O(N^3) Hungarian method, with none of the pruning under test.
double DenseWasserstein(const std::vector<Point>& a, const std::vector<Point>& b, double p) {
  const int n = int(a.size()), m = int(b.size()), size = n + m;
  if (size == 0) return 0;
  auto cost = [&](int row, int col) {  // rows: a then b̄; columns: b then ā
    if (row < n && col < m) return std::pow(GroundCost(a[row], b[col]), p);
    if (row < n) return col - m == row ? std::pow(DiagonalCost(a[row]), p) : kInf;
    if (col < m) return col == row - n ? std::pow(DiagonalCost(b[col]), p) : kInf;
    return 0.0;
  };
  std::vector<double> u(size + 1, 0), v(size + 1, 0), way_cost(size + 1);
  std::vector<int> match(size + 1, 0), way(size + 1, 0);
  for (int row = 1; row <= size; ++row) {
    match[0] = row;
    int col0 = 0;
    std::fill(way_cost.begin(), way_cost.end(), kInf);
    std::vector<bool> used(size + 1, false);
    do {
      used[col0] = true;
      const int row0 = match[col0];
      double delta = kInf;
      int col1 = 0;
      for (int col = 1; col <= size; ++col) {
        if (used[col]) continue;
        const double reduced = cost(row0 - 1, col - 1) - u[row0] - v[col];
        if (reduced < way_cost[col]) {
          way_cost[col] = reduced;
          way[col] = col0;
        }
        if (way_cost[col] < delta) {
          delta = way_cost[col];
          col1 = col;
        }
      }
      for (int col = 0; col <= size; ++col) {
        if (used[col]) {
          u[match[col]] += delta;
          v[col] -= delta;
        } else {
          way_cost[col] -= delta;
        }
      }
      col0 = col1;
    } while (match[col0] != 0);
    do {
      const int col1 = way[col0];
      match[col0] = match[col1];
      col0 = col1;
    } while (col0 != 0);
  }
  double sum = 0;
  for (int col = 1; col <= size; ++col) sum += cost(match[col] - 1, col - 1);
  return std::pow(sum, 1 / p);
}

// The dense bottleneck: the least candidate cost at which Kuhn's augmenting paths match every
// point, every a_i facing every b_j.
double DenseBottleneck(const std::vector<Point>& a, const std::vector<Point>& b) {
  const int n = int(a.size()), m = int(b.size()), size = n + m;
  std::vector<double> candidates = {0};
  for (const Point& x : a) candidates.push_back(DiagonalCost(x));
  for (const Point& y : b) candidates.push_back(DiagonalCost(y));
  for (const Point& x : a) {
    for (const Point& y : b) candidates.push_back(GroundCost(x, y));
  }
  std::sort(candidates.begin(), candidates.end());
  auto feasible = [&](double r) {
    auto edge = [&](int row, int col) {
      if (row < n && col < m) return GroundCost(a[row], b[col]) <= r;
      if (row < n) return col - m == row && DiagonalCost(a[row]) <= r;
      if (col < m) return col == row - n && DiagonalCost(b[col]) <= r;
      return true;
    };
    std::vector<int> match(size, -1);
    for (int row = 0; row < size; ++row) {
      std::vector<bool> seen(size, false);
      std::function<bool(int)> try_row = [&](int x) {
        for (int col = 0; col < size; ++col) {
          if (!edge(x, col) || seen[col]) continue;
          seen[col] = true;
          if (match[col] < 0 || try_row(match[col])) {
            match[col] = x;
            return true;
          }
        }
        return false;
      };
      if (!try_row(row)) return false;
    }
    return true;
  };
  for (double r : candidates) {
    if (feasible(r)) return r;
  }
  return kInf;
}

// Every point of both lists exactly once, costs as the ground metric says, value from them.
void ExpectValidMatching(const MatchingResult& result, const std::vector<Point>& a,
                         const std::vector<Point>& b, double p) {
  std::vector<int> seen_a(a.size()), seen_b(b.size());
  double sum = 0, largest = 0;
  for (const Match& match : result.matches) {
    ASSERT_FALSE(match.a < 0 && match.b < 0);
    double cost = 0;
    if (match.a >= 0 && match.b >= 0) {
      cost = GroundCost(a[match.a], b[match.b]);
    } else if (match.a >= 0) {
      cost = DiagonalCost(a[match.a]);
    } else {
      cost = DiagonalCost(b[match.b]);
    }
    EXPECT_EQ(match.cost, cost);
    if (match.a >= 0) ++seen_a[match.a];
    if (match.b >= 0) ++seen_b[match.b];
    sum += std::pow(cost, p);
    largest = std::max(largest, cost);
  }
  for (int count : seen_a) EXPECT_EQ(count, 1);
  for (int count : seen_b) EXPECT_EQ(count, 1);
  if (std::isinf(p)) {
    EXPECT_EQ(result.value, largest);
  } else {
    EXPECT_NEAR(result.value, std::pow(sum, 1 / p), 1e-12 * std::max(1.0, result.value));
  }
}

TEST(WassersteinMatching, EqualsExhaustionOnSmallDiagrams) {
  std::mt19937 rng(7);
  for (int trial = 0; trial < 300; ++trial) {
    const bool ties = trial % 3 == 0;
    const std::vector<Point> a = RandomDiagram(int(rng() % 6), rng, ties);
    const std::vector<Point> b = RandomDiagram(int(rng() % 6), rng, ties);
    for (const double p : {1.0, 2.0, 3.5}) {
      const MatchingResult w = WassersteinMatching(a, b, p);
      ExpectValidMatching(w, a, b, p);
      EXPECT_NEAR(w.value, ExhaustiveWasserstein(a, b, p), 1e-12 * std::max(1.0, w.value))
          << "trial " << trial << ", p " << p;
    }
  }
}

TEST(WassersteinMatching, EqualsTheDenseHungarianMethod) {
  std::mt19937 rng(11);
  for (int trial = 0; trial < 30; ++trial) {
    const bool ties = trial % 2 == 0;
    const std::vector<Point> a = RandomDiagram(20 + int(rng() % 60), rng, ties);
    const std::vector<Point> b = RandomDiagram(20 + int(rng() % 60), rng, ties);
    for (const double p : {1.0, 2.0, 3.0}) {
      const MatchingResult w = WassersteinMatching(a, b, p);
      ExpectValidMatching(w, a, b, p);
      EXPECT_NEAR(w.value, DenseWasserstein(a, b, p), 1e-10 * std::max(1.0, w.value))
          << "trial " << trial << ", p " << p;
    }
  }
}

TEST(BottleneckMatching, EqualsExhaustionAndTheDenseSearch) {
  std::mt19937 rng(13);
  for (int trial = 0; trial < 300; ++trial) {
    const bool ties = trial % 3 == 0;
    const std::vector<Point> a = RandomDiagram(int(rng() % 6), rng, ties);
    const std::vector<Point> b = RandomDiagram(int(rng() % 6), rng, ties);
    const MatchingResult bn = BottleneckMatching(a, b);
    ExpectValidMatching(bn, a, b, kInf);
    EXPECT_EQ(bn.value, ExhaustiveBottleneck(a, b)) << "trial " << trial;
  }
  for (int trial = 0; trial < 20; ++trial) {
    const std::vector<Point> a = RandomDiagram(20 + int(rng() % 50), rng, trial % 2 == 0);
    const std::vector<Point> b = RandomDiagram(20 + int(rng() % 50), rng, trial % 2 == 0);
    const MatchingResult bn = BottleneckMatching(a, b);
    ExpectValidMatching(bn, a, b, kInf);
    EXPECT_EQ(bn.value, DenseBottleneck(a, b)) << "trial " << trial;
  }
}

TEST(Matching, EmptyDiagramsAndPointsOnTheDiagonal) {
  EXPECT_EQ(WassersteinMatching({}, {}, 2).value, 0);
  EXPECT_TRUE(WassersteinMatching({}, {}, 2).matches.empty());
  EXPECT_EQ(BottleneckMatching({}, {}).value, 0);
  const std::vector<Point> a = {{1, 3}, {2, 2}};
  // Against nothing: everything goes to the diagonal, (3 - 1) / 2 = 1 and 0.
  EXPECT_DOUBLE_EQ(WassersteinMatching(a, {}, 2).value, 1);
  EXPECT_DOUBLE_EQ(BottleneckMatching({}, a).value, 1);
  // A diagram against itself is at distance 0.
  EXPECT_EQ(WassersteinMatching(a, a, 2).value, 0);
  EXPECT_EQ(BottleneckMatching(a, a).value, 0);
}

TEST(Matching, KnownValues) {
  // (0, 4) against (1, 4.5): matched at max(1, 0.5) = 1, cheaper than 2 and 1.75 on the diagonal.
  const std::vector<Point> a = {{0, 4}}, b = {{1, 4.5}};
  EXPECT_DOUBLE_EQ(WassersteinMatching(a, b, 2).value, 1);
  EXPECT_DOUBLE_EQ(BottleneckMatching(a, b).value, 1);
  // (0, 1) against (5, 6): both to the diagonal, 0.5 each: W2 = sqrt(0.5), bottleneck 0.5.
  const std::vector<Point> c = {{0, 1}}, d = {{5, 6}};
  EXPECT_DOUBLE_EQ(WassersteinMatching(c, d, 2).value, std::sqrt(0.5));
  EXPECT_DOUBLE_EQ(BottleneckMatching(c, d).value, 0.5);
}

}  // namespace
}  // namespace actopo::diagrams
