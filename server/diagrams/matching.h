// Optimal matchings between two persistence diagrams of one pair type: the exact Wasserstein-p
// and bottleneck distances of SEMANTICS.md ("Distances between persistence diagrams"), the
// definitions of Hera and Gudhi (internal_p = infinity).
//
// A point (birth, death) of one diagram is matched to one point of the other, at the L-infinity
// distance max(|b1 - b2|, |d1 - d2|), or to the diagonal, at (death - birth) / 2. The
// Wasserstein-p distance is the p-th root of the least sum of cost^p over such matchings; the
// bottleneck distance the least largest cost.
//
//   std::vector<Point> a = ..., b = ...;
//   MatchingResult w = WassersteinMatching(a, b, /*p=*/2);   // w.value, w.matches
//   MatchingResult bn = BottleneckMatching(a, b);
//
// Both reduce the problem to a perfect matching of size |a| + |b| in a bipartite graph (the
// diagonal copies of Kerber, Morozov, Nigmetov, "Geometry Helps to Compare Persistence
// Diagrams", JEA 2017): a point a_i faces every b_j and its own diagonal copy; b_j's diagonal
// copy faces b_j and the diagonal copy of every a_i, at no cost. Two facts keep the graph sparse
// and the answer exact: an edge (a_i, b_j) costing more than sending both to the diagonal is in
// no optimal matching (so it is left out), and the diagonal copies only ever need to pair along
// the edges kept (the transposes), since any pairing of them costs nothing. Wasserstein then runs
// successive shortest paths with potentials (Dijkstra on reduced costs), whose final potentials
// are a dual certificate of optimality; bottleneck runs Hopcroft-Karp on the edges below each
// candidate value, found by binary search.
#ifndef ACTOPO_SERVER_DIAGRAMS_MATCHING_H_
#define ACTOPO_SERVER_DIAGRAMS_MATCHING_H_

#include <cstdint>
#include <span>
#include <vector>

namespace actopo::diagrams {

// A finite pair as a point of the (birth, death) plane; death >= birth.
struct Point {
  double birth = 0;
  double death = 0;
};

// max(|b1 - b2|, |d1 - d2|).
double GroundCost(const Point& x, const Point& y);
// The L-infinity distance to the diagonal: (death - birth) / 2.
double DiagonalCost(const Point& x);

// One link of a matching: indices into the two point lists, -1 for the diagonal (never both).
struct Match {
  int32_t a = -1;
  int32_t b = -1;
  double cost = 0;  // GroundCost or DiagonalCost, not raised to p
};

struct MatchingResult {
  // Wasserstein: (sum of cost^p)^(1/p); bottleneck: the largest cost. 0 for two empty lists.
  double value = 0;
  // Every point of both lists exactly once: pairs (a, b) and points sent to the diagonal.
  std::vector<Match> matches;
};

// The exact Wasserstein-p matching, p >= 1.
MatchingResult WassersteinMatching(std::span<const Point> a, std::span<const Point> b, double p);

// The exact bottleneck matching.
MatchingResult BottleneckMatching(std::span<const Point> a, std::span<const Point> b);

}  // namespace actopo::diagrams

#endif  // ACTOPO_SERVER_DIAGRAMS_MATCHING_H_
