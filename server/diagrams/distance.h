// Distances between persistence diagrams (SEMANTICS.md "Distances between persistence
// diagrams"; TTK's BottleneckDistance and PersistenceDiagramDistanceMatrix): per pair type, the
// exact Wasserstein-p and bottleneck matchings of matching.h, combined over the types.
//
//   Diagram x = ToDiagram(diagram_of_field_1, /*min_persistence=*/0);
//   Diagram y = ToDiagram(diagram_of_field_2, 0);
//   Distance d = ComputeDistance(x, y, {.p = 2});            // d.wasserstein, d.bottleneck
//   DistanceMatrix all = ComputeDistanceMatrix(diagrams, {.p = 2}, {.threads = 2});
#ifndef ACTOPO_SERVER_DIAGRAMS_DISTANCE_H_
#define ACTOPO_SERVER_DIAGRAMS_DISTANCE_H_

#include <array>
#include <cstdint>
#include <functional>
#include <span>
#include <vector>

#include "absl/status/status.h"
#include "server/algorithms/persistence_diagram.h"
#include "server/diagrams/matching.h"

namespace actopo::diagrams {

inline constexpr int kPairTypes = 3;  // 0 min-saddle, 1 saddle-saddle, 2 saddle-max

// A persistence diagram as the distances see it: per pair type, the finite pairs as points and
// the births of the essential (infinite) pairs, each with the index of its pair in the diagram
// it came from.
struct Diagram {
  std::array<std::vector<Point>, kPairTypes> points;
  std::array<std::vector<int32_t>, kPairTypes> point_pairs;
  std::array<std::vector<double>, kPairTypes> essential;
  std::array<std::vector<int32_t>, kPairTypes> essential_pairs;

  int64_t size() const;  // finite and essential pairs
};

// The pairs of `diagram` whose persistence is at least `min_persistence` (all of them at 0;
// essential pairs are always kept).
Diagram ToDiagram(const PersistenceDiagramResult& diagram, double min_persistence = 0);

struct DistanceOptions {
  double p = 2;  // Wasserstein order, at least 1
  // Match the essential pairs too, within a type by birth (cost |b1 - b2|); a distance is
  // infinite when two diagrams have different numbers of them (Gudhi's keep_essential_parts).
  bool essential = false;
  // Keep the matchings behind the distances (Distance::matching).
  bool matching = false;
};

// "p: 0.5 is below 1", naming the option.
absl::Status ValidateDistanceOptions(const DistanceOptions& options);

// A pair of the first diagram matched to one of the second (pair indices; -1 the diagonal).
struct PairMatch {
  int8_t type = 0;
  int32_t pair_a = -1;
  int32_t pair_b = -1;
  double cost = 0;
};

struct Distance {
  double wasserstein = 0;  // (sum over types of W_p^p)^(1/p)
  double bottleneck = 0;   // the largest over types
  std::array<double, kPairTypes> wasserstein_by_type{};
  std::array<double, kPairTypes> bottleneck_by_type{};
  // With DistanceOptions::matching: the Wasserstein-p matching, every pair of both diagrams
  // once, by type, then the first diagram's pairs in order, then the second's sent to the
  // diagonal; essential pairs included when matched.
  std::vector<PairMatch> matching;
};

Distance ComputeDistance(const Diagram& x, const Diagram& y, const DistanceOptions& options);

// Symmetric n x n matrices, row-major, with a zero diagonal.
struct DistanceMatrix {
  int32_t size = 0;
  std::vector<double> wasserstein;
  std::vector<double> bottleneck;
  double at(const std::vector<double>& m, int32_t i, int32_t j) const { return m[i * size + j]; }
};

struct MatrixOptions {
  int threads = 1;  // the entries run in parallel, largest diagrams first
  // Entries done of the n(n-1)/2, from any thread, never two at once; cheap.
  std::function<void(int64_t done, int64_t total)> progress;
  // Polled between entries: when it returns true the rest is skipped (the caller reports why).
  std::function<bool()> stopped;
};

DistanceMatrix ComputeDistanceMatrix(std::span<const Diagram> diagrams,
                                     const DistanceOptions& options,
                                     const MatrixOptions& matrix = {});

}  // namespace actopo::diagrams

#endif  // ACTOPO_SERVER_DIAGRAMS_DISTANCE_H_
