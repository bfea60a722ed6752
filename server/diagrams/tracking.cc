#include "server/diagrams/tracking.h"

#include <map>

#include "server/core/parallel.h"

namespace actopo::diagrams {

Tracking TrackPairs(std::span<const Diagram> steps, const DistanceOptions& options, int threads) {
  Tracking out;
  const int64_t links = std::max<int64_t>(int64_t(steps.size()) - 1, 0);
  out.steps.resize(size_t(links));
  DistanceOptions with_matching = options;
  with_matching.matching = true;
  ParallelFor(links, threads, [&](int64_t t, int) {
    out.steps[t] = ComputeDistance(steps[t], steps[t + 1], with_matching);
  });
  // next[t][(type, pair)] = (pair at t + 1, cost); a pair with a predecessor starts nothing.
  std::vector<std::map<std::pair<int8_t, int32_t>, std::pair<int32_t, double>>> next(links);
  std::vector<std::map<std::pair<int8_t, int32_t>, bool>> reached(steps.size());
  for (int64_t t = 0; t < links; ++t) {
    for (const PairMatch& m : out.steps[t].matching) {
      if (m.pair_a < 0 || m.pair_b < 0) continue;  // the diagonal ends a trajectory
      next[t][{m.type, m.pair_a}] = {m.pair_b, m.cost};
      reached[t + 1][{m.type, m.pair_b}] = true;
    }
  }
  for (int64_t t = 0; t < links; ++t) {
    for (const auto& [start, link] : next[t]) {
      if (reached[t].contains(start)) continue;  // a link inside a trajectory begun earlier
      Trajectory trajectory{.type = start.first, .first_step = int32_t(t), .pairs = {start.second}};
      int32_t pair = start.second;
      for (int64_t s = t; s < links; ++s) {
        const auto it = next[s].find({start.first, pair});
        if (it == next[s].end()) break;
        pair = it->second.first;
        trajectory.pairs.push_back(pair);
        trajectory.costs.push_back(it->second.second);
      }
      out.trajectories.push_back(std::move(trajectory));
    }
  }
  std::stable_sort(out.trajectories.begin(), out.trajectories.end(),
                   [](const Trajectory& a, const Trajectory& b) {
                     return std::tie(a.type, a.first_step, a.pairs[0]) <
                            std::tie(b.type, b.first_step, b.pairs[0]);
                   });
  // Each step's matching stays in out.steps (a caller may want it); the links came from it.
  return out;
}

}  // namespace actopo::diagrams
