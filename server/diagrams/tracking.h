// Tracking over time (SEMANTICS.md "Tracking over time"; TTK's TrackingFromPersistenceDiagrams):
// the diagrams of consecutive steps of a series matched by the optimal Wasserstein-2 matching
// of each pair type (matching.h); a pair of step t linked to at most one pair of step t + 1;
// chains of links are trajectories; a pair sent to the diagonal ends (or starts) one.
//
//   std::vector<Diagram> steps = ...;                // one per step, in time order
//   Tracking tracking = TrackPairs(steps, {.p = 2}, /*threads=*/2);
//   for (const Trajectory& t : tracking.trajectories) ... t.pairs[k] is the pair at t.first + k
#ifndef ACTOPO_SERVER_DIAGRAMS_TRACKING_H_
#define ACTOPO_SERVER_DIAGRAMS_TRACKING_H_

#include <cstdint>
#include <span>
#include <vector>

#include "server/diagrams/distance.h"

namespace actopo::diagrams {

struct Trajectory {
  int8_t type = 0;
  int32_t first_step = 0;      // the step of pairs[0]
  std::vector<int32_t> pairs;  // pair indices in their steps' diagrams, consecutive steps
  std::vector<double> costs;   // the link from pairs[k] to pairs[k + 1] (pairs.size() - 1)
};

struct Tracking {
  // Every chain of at least one link, by type, then first step, then first pair.
  std::vector<Trajectory> trajectories;
  // Per consecutive steps (t, t + 1): the Wasserstein-p distance of their optimal matching,
  // per pair type and combined (the distance between the two diagrams).
  std::vector<Distance> steps;
};

// Matches every two consecutive steps (in parallel on `threads`) and chains the links. Pairs
// matched to the diagonal link nothing; essential pairs link only with options.essential.
Tracking TrackPairs(std::span<const Diagram> steps, const DistanceOptions& options,
                    int threads = 1);

}  // namespace actopo::diagrams

#endif  // ACTOPO_SERVER_DIAGRAMS_TRACKING_H_
