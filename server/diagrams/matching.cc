#include "server/diagrams/matching.h"

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <queue>
#include <utility>

namespace actopo::diagrams {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

double Power(double x, double p) { return p == 2 ? x * x : p == 1 ? x : std::pow(x, p); }

// The candidate edges (a_i, b_j): those for which keep(delta_i, delta_j, cost) holds (delta: the
// points' diagonal costs), by ascending i then j.
struct Candidates {
  int32_t n = 0, m = 0;
  std::vector<double> delta_a, delta_b;
  std::vector<int32_t> i, j;
  std::vector<double> cost;
};

Candidates FindCandidates(std::span<const Point> a, std::span<const Point> b,
                          const std::function<bool(double, double, double)>& keep) {
  Candidates c;
  c.n = int32_t(a.size());
  c.m = int32_t(b.size());
  c.delta_a.resize(c.n);
  c.delta_b.resize(c.m);
  for (int32_t i = 0; i < c.n; ++i) c.delta_a[i] = DiagonalCost(a[i]);
  for (int32_t j = 0; j < c.m; ++j) c.delta_b[j] = DiagonalCost(b[j]);
  // An edge needs at least cost < delta_i + delta_j (both rules imply it), and cost >=
  // |birth_i - birth_j|. The few most persistent points of b face every a_i; the others, sorted
  // by birth, only those within delta_i + (their largest delta) of a_i's birth.
  std::vector<int32_t> by_delta(c.m);
  for (int32_t j = 0; j < c.m; ++j) by_delta[j] = j;
  const int32_t far = std::min<int32_t>(c.m, 32);
  std::partial_sort(by_delta.begin(), by_delta.begin() + far, by_delta.end(),
                    [&](int32_t x, int32_t y) { return c.delta_b[x] > c.delta_b[y]; });
  const std::vector<int32_t> reaching(by_delta.begin(), by_delta.begin() + far);
  std::vector<int32_t> by_birth(by_delta.begin() + far, by_delta.end());
  double near_delta = 0;
  for (int32_t j : by_birth) near_delta = std::max(near_delta, c.delta_b[j]);
  std::sort(by_birth.begin(), by_birth.end(),
            [&](int32_t x, int32_t y) { return b[x].birth < b[y].birth; });
  std::vector<double> births(by_birth.size());
  for (size_t k = 0; k < by_birth.size(); ++k) births[k] = b[by_birth[k]].birth;
  std::vector<std::pair<int32_t, double>> row;
  for (int32_t i = 0; i < c.n; ++i) {
    row.clear();
    auto consider = [&](int32_t j) {
      const double cost = GroundCost(a[i], b[j]);
      if (cost < c.delta_a[i] + c.delta_b[j] && keep(c.delta_a[i], c.delta_b[j], cost)) {
        row.emplace_back(j, cost);
      }
    };
    for (int32_t j : reaching) consider(j);
    const double reach = c.delta_a[i] + near_delta;
    for (auto it = std::lower_bound(births.begin(), births.end(), a[i].birth - reach);
         it != births.end() && *it <= a[i].birth + reach; ++it) {
      consider(by_birth[it - births.begin()]);
    }
    std::sort(row.begin(), row.end());
    for (const auto& [j, cost] : row) {
      c.i.push_back(i);
      c.j.push_back(j);
      c.cost.push_back(cost);
    }
  }
  return c;
}

// The bipartite graph of the header's reduction over the candidates marked in `kept` (all of
// them when it is empty). Left nodes: a_0 .. a_{n-1}, then the diagonal copies of b (n + j);
// right nodes: b_0 .. b_{m-1}, then the diagonal copies of a (m + i). Edges in CSR by left node;
// every left node has its diagonal edge, so the graph always has the perfect matching that
// sends everything to the diagonal. A candidate (a_i, b_j) brings its transpose (b̄_j, ā_i),
// weighted 0 but existing at the same thresholds.
struct Graph {
  int32_t n = 0, m = 0;
  std::vector<int32_t> start;  // n + m + 1 offsets into the edge arrays
  std::vector<int32_t> right;
  std::vector<double> weight;  // what the matching minimizes: cost^p (Wasserstein)
  std::vector<double> ground;  // the ground cost deciding whether the edge exists at a threshold
  int32_t size() const { return n + m; }
};

Graph MakeGraph(const Candidates& c, const std::vector<uint8_t>& kept, double p) {
  Graph g;
  g.n = c.n;
  g.m = c.m;
  const int32_t n = c.n, m = c.m;
  auto in = [&](size_t e) { return kept.empty() || kept[e]; };
  g.start.assign(size_t(n + m) + 1, 0);
  for (int32_t l = 0; l < n + m; ++l) g.start[l + 1] = 1;  // the diagonal edges
  for (size_t e = 0; e < c.i.size(); ++e) {
    if (!in(e)) continue;
    ++g.start[c.i[e] + 1];
    ++g.start[n + c.j[e] + 1];
  }
  for (int32_t l = 0; l < n + m; ++l) g.start[l + 1] += g.start[l];
  const size_t edges = g.start.back();
  g.right.resize(edges);
  g.weight.resize(edges);
  g.ground.resize(edges);
  std::vector<int32_t> fill(g.start.begin(), g.start.end() - 1);
  auto add = [&](int32_t l, int32_t r, double weight, double ground) {
    const int32_t e = fill[l]++;
    g.right[e] = r;
    g.weight[e] = weight;
    g.ground[e] = ground;
  };
  for (int32_t j = 0; j < m; ++j) add(n + j, j, Power(c.delta_b[j], p), c.delta_b[j]);
  for (size_t e = 0; e < c.i.size(); ++e) {
    if (!in(e)) continue;
    add(c.i[e], c.j[e], Power(c.cost[e], p), c.cost[e]);
    add(n + c.j[e], m + c.i[e], 0, c.cost[e]);
  }
  for (int32_t i = 0; i < n; ++i) add(i, m + i, Power(c.delta_a[i], p), c.delta_a[i]);
  return g;
}

// The matches a perfect matching of the graph stands for (left node -> right node), with their
// ground costs; diagonal copies paired with each other stand for nothing.
std::vector<Match> ToMatches(int32_t n, int32_t m, const std::vector<int32_t>& match_left,
                             std::span<const Point> a, std::span<const Point> b) {
  std::vector<Match> matches;
  matches.reserve(n + m);
  for (int32_t i = 0; i < n; ++i) {
    const int32_t r = match_left[i];
    if (r < m) {
      matches.push_back({i, r, GroundCost(a[i], b[r])});
    } else {
      matches.push_back({i, -1, DiagonalCost(a[i])});
    }
  }
  for (int32_t j = 0; j < m; ++j) {
    if (match_left[n + j] == j) matches.push_back({-1, j, DiagonalCost(b[j])});
  }
  return matches;
}

// Minimum-weight perfect matching by successive shortest paths: each free left node in turn
// grows a Dijkstra tree on reduced weights (weight - u[l] - v[r] >= 0, 0 on matched edges)
// until it reaches a free right node, then the potentials move so that the tree's edges stay
// tight, and the path is augmented. The potentials persist across calls on graphs over the same
// nodes, so that a caller can add edges and go on (MinWeightMatching).
struct ShortestPaths {
  explicit ShortestPaths(int32_t size)
      : u(size, 0),
        v(size, 0),
        match_left(size, -1),
        match_right(size, -1),
        dist(size, kInf),
        pred(size, -1),
        done(size, 0) {}

  // Column reduction, row reduction, then every left node takes a free right node on a tight
  // edge: most nodes start matched.
  void Start(const Graph& g) {
    std::fill(v.begin(), v.end(), kInf);
    for (size_t e = 0; e < g.right.size(); ++e)
      v[g.right[e]] = std::min(v[g.right[e]], g.weight[e]);
    for (int32_t l = 0; l < g.size(); ++l) {
      double best = kInf;
      for (int32_t e = g.start[l]; e < g.start[l + 1]; ++e) {
        best = std::min(best, g.weight[e] - v[g.right[e]]);
      }
      u[l] = best;
      for (int32_t e = g.start[l]; e < g.start[l + 1]; ++e) {
        const int32_t r = g.right[e];
        if (g.weight[e] - v[r] == best && match_right[r] < 0) {
          match_left[l] = r;
          match_right[r] = l;
          break;
        }
      }
    }
  }

  // Matches every free left node.
  void Augment(const Graph& g) {
    for (int32_t s = 0; s < g.size(); ++s) {
      if (match_left[s] < 0) AugmentFrom(g, s);
    }
  }

  void Unmatch(int32_t l) {
    if (match_left[l] < 0) return;
    match_right[match_left[l]] = -1;
    match_left[l] = -1;
  }

  std::vector<double> u, v;
  std::vector<int32_t> match_left, match_right;

 private:
  void Relax(const Graph& g, int32_t l, double base) {
    for (int32_t e = g.start[l]; e < g.start[l + 1]; ++e) {
      const int32_t r = g.right[e];
      if (done[r]) continue;
      const double reduced = g.weight[e] - u[l] - v[r];
      const double d = reduced > 0 ? base + reduced : base;
      if (d < dist[r]) {
        if (dist[r] == kInf) touched.push_back(r);
        dist[r] = d;
        pred[r] = l;
        // Tight edges (many: matched ones, transposes) reach r at the distance just taken,
        // the least there is: r goes next without the heap.
        if (d == base) {
          level.push_back(r);
        } else {
          heap.emplace(d, r);
        }
      }
    }
  }

  void AugmentFrom(const Graph& g, int32_t s) {
    Relax(g, s, 0);
    int32_t free_right = -1;
    while (!level.empty() || !heap.empty()) {
      int32_t r;
      if (!level.empty()) {
        r = level.back();
        level.pop_back();
      } else {
        r = heap.top().second;
        const double d = heap.top().first;
        heap.pop();
        if (d > dist[r]) continue;
      }
      if (done[r]) continue;
      const double d = dist[r];
      done[r] = 1;
      finalized.push_back(r);
      if (match_right[r] < 0) {
        free_right = r;
        break;
      }
      Relax(g, match_right[r], d);
    }
    // free_right >= 0: the graph has a perfect matching, so an augmenting path exists.
    const double total = dist[free_right];
    u[s] += total;
    for (int32_t r : finalized) {
      if (r == free_right) continue;
      const double shift = total - dist[r];
      v[r] -= shift;
      u[match_right[r]] += shift;
    }
    for (int32_t r = free_right;;) {
      const int32_t l = pred[r];
      const int32_t next = match_left[l];
      match_left[l] = r;
      match_right[r] = l;
      if (l == s) break;
      r = next;
    }
    for (int32_t r : touched) {
      dist[r] = kInf;
      pred[r] = -1;
      done[r] = 0;
    }
    touched.clear();
    finalized.clear();
    level.clear();
    heap = {};
  }

  std::vector<double> dist;
  std::vector<int32_t> pred;
  std::vector<uint8_t> done;
  std::vector<int32_t> touched, finalized;
  std::vector<int32_t> level;  // reached at the distance of the node last taken
  using Entry = std::pair<double, int32_t>;
  std::priority_queue<Entry, std::vector<Entry>, std::greater<>> heap;
};

// Each a_i's and each b_j's cheapest candidates, this many: where optimal matchings almost
// always find their pairs. The rest join only where the potentials say they must.
constexpr int kNearest = 8;

// The minimum-weight perfect matching over every candidate, solved on a subgraph that grows:
// the kNearest cheapest candidates of every point first; then while some candidate left out
// has a negative reduced weight under the potentials (they are no dual certificate yet), those
// join, their left nodes' potentials drop to keep every reduced weight non-negative, and the
// left nodes whose matched edge is no longer tight are matched again. Once none is negative the
// potentials certify the matching optimal over all the candidates.
std::vector<int32_t> MinWeightMatching(const Candidates& c, double p) {
  const size_t pairs = c.i.size();
  std::vector<uint8_t> kept(pairs, 0);
  {
    std::vector<std::vector<std::pair<double, size_t>>> of_b(c.m);
    for (size_t e = 0, row = 0; e < pairs; e = row) {
      std::vector<std::pair<double, size_t>> of_a;
      for (row = e; row < pairs && c.i[row] == c.i[e]; ++row) {
        of_a.emplace_back(c.cost[row], row);
        of_b[c.j[row]].emplace_back(c.cost[row], row);
      }
      const size_t k = std::min<size_t>(kNearest, of_a.size());
      std::partial_sort(of_a.begin(), of_a.begin() + k, of_a.end());
      for (size_t x = 0; x < k; ++x) kept[of_a[x].second] = 1;
    }
    for (auto& of : of_b) {
      const size_t k = std::min<size_t>(kNearest, of.size());
      std::partial_sort(of.begin(), of.begin() + k, of.end());
      for (size_t x = 0; x < k; ++x) kept[of[x].second] = 1;
    }
  }
  Graph g = MakeGraph(c, kept, p);
  ShortestPaths paths(g.size());
  paths.Start(g);
  double largest = 0;
  for (double w : g.weight) largest = std::max(largest, w);
  for (size_t e = 0; e < pairs; ++e) largest = std::max(largest, Power(c.cost[e], p));
  // Reduced weights this far below 0 are rounding, not a missing edge.
  const double tolerance = 1e-13 * std::max(largest, 1e-300);
  for (;;) {
    paths.Augment(g);
    bool grew = false;
    for (size_t e = 0; e < pairs; ++e) {
      if (kept[e]) continue;
      const int32_t a = c.i[e], b_bar = c.n + c.j[e];
      const double w = Power(c.cost[e], p);
      const double reduced = w - paths.u[a] - paths.v[c.j[e]];
      const double reduced_transpose = -paths.u[b_bar] - paths.v[c.m + a];
      if (reduced >= -tolerance && reduced_transpose >= -tolerance) continue;
      kept[e] = 1;
      grew = true;
      if (reduced < 0) {
        paths.u[a] += reduced;
        paths.Unmatch(a);
      }
      if (reduced_transpose < 0) {
        paths.u[b_bar] += reduced_transpose;
        paths.Unmatch(b_bar);
      }
    }
    if (!grew) break;
    g = MakeGraph(c, kept, p);
  }
  return paths.match_left;
}

// Hopcroft-Karp on the edges whose ground cost is at most `threshold`: true when the matching
// is perfect, then left in `match_left`.
bool PerfectMatchingBelow(const Graph& g, double threshold, std::vector<int32_t>& match_left) {
  const int32_t size = g.size();
  match_left.assign(size, -1);
  std::vector<int32_t> match_right(size, -1), layer(size), next_edge(size);
  constexpr int32_t kUnreached = std::numeric_limits<int32_t>::max();
  int32_t matched = 0;
  // Greedy start.
  for (int32_t l = 0; l < size; ++l) {
    for (int32_t e = g.start[l]; e < g.start[l + 1]; ++e) {
      if (g.ground[e] <= threshold && match_right[g.right[e]] < 0) {
        match_left[l] = g.right[e];
        match_right[g.right[e]] = l;
        ++matched;
        break;
      }
    }
  }
  std::vector<int32_t> queue;
  std::function<bool(int32_t)> augment = [&](int32_t l) {
    for (int32_t& e = next_edge[l]; e < g.start[l + 1]; ++e) {
      if (g.ground[e] > threshold) continue;
      const int32_t r = g.right[e];
      const int32_t other = match_right[r];
      if (other < 0 || (layer[other] == layer[l] + 1 && augment(other))) {
        match_left[l] = r;
        match_right[r] = l;
        ++e;
        return true;
      }
    }
    layer[l] = kUnreached;
    return false;
  };
  while (matched < size) {
    queue.clear();
    for (int32_t l = 0; l < size; ++l) {
      layer[l] = match_left[l] < 0 ? 0 : kUnreached;
      if (layer[l] == 0) queue.push_back(l);
    }
    bool found = false;
    for (size_t k = 0; k < queue.size(); ++k) {
      const int32_t l = queue[k];
      for (int32_t e = g.start[l]; e < g.start[l + 1]; ++e) {
        if (g.ground[e] > threshold) continue;
        const int32_t other = match_right[g.right[e]];
        if (other < 0) {
          found = true;
        } else if (layer[other] == kUnreached) {
          layer[other] = layer[l] + 1;
          queue.push_back(other);
        }
      }
    }
    if (!found) return false;
    for (int32_t l = 0; l < size; ++l) next_edge[l] = g.start[l];
    for (int32_t l = 0; l < size; ++l) {
      if (match_left[l] < 0 && augment(l)) ++matched;
    }
  }
  return true;
}

}  // namespace

double GroundCost(const Point& x, const Point& y) {
  return std::max(std::abs(x.birth - y.birth), std::abs(x.death - y.death));
}

double DiagonalCost(const Point& x) { return (x.death - x.birth) / 2; }

MatchingResult WassersteinMatching(std::span<const Point> a, std::span<const Point> b, double p) {
  // (a_i, b_j) is worth keeping only when it costs less than sending both to the diagonal.
  const Candidates c = FindCandidates(a, b, [p](double delta_a, double delta_b, double cost) {
    return Power(cost, p) < Power(delta_a, p) + Power(delta_b, p);
  });
  MatchingResult result;
  result.matches = ToMatches(c.n, c.m, MinWeightMatching(c, p), a, b);
  double sum = 0;
  for (const Match& match : result.matches) sum += Power(match.cost, p);
  result.value = p == 1 ? sum : std::pow(sum, 1 / p);
  return result;
}

MatchingResult BottleneckMatching(std::span<const Point> a, std::span<const Point> b) {
  // (a_i, b_j) is worth keeping only when it costs less than the larger of the two diagonal
  // costs, which sending both to the diagonal would pay.
  const Graph g = MakeGraph(FindCandidates(a, b,
                                           [](double delta_a, double delta_b, double cost) {
                                             return cost < std::max(delta_a, delta_b);
                                           }),
                            {}, 1);
  MatchingResult result;
  if (g.size() == 0) return result;
  std::vector<double> candidates = g.ground;
  std::sort(candidates.begin(), candidates.end());
  candidates.erase(std::unique(candidates.begin(), candidates.end()), candidates.end());
  // The largest candidate is at least every diagonal cost: the all-diagonal matching is there.
  size_t lo = 0, hi = candidates.size() - 1;
  std::vector<int32_t> match_left;
  while (lo < hi) {
    const size_t mid = lo + (hi - lo) / 2;
    if (PerfectMatchingBelow(g, candidates[mid], match_left)) {
      hi = mid;
    } else {
      lo = mid + 1;
    }
  }
  PerfectMatchingBelow(g, candidates[lo], match_left);
  result.matches = ToMatches(g.n, g.m, match_left, a, b);
  for (const Match& match : result.matches) result.value = std::max(result.value, match.cost);
  return result;
}

}  // namespace actopo::diagrams
