#include "server/diagrams/distance.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <limits>
#include <mutex>

#include "absl/strings/str_cat.h"
#include "server/core/parallel.h"

namespace actopo::diagrams {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

double Power(double x, double p) { return p == 2 ? x * x : p == 1 ? x : std::pow(x, p); }
double Root(double x, double p) { return p == 2 ? std::sqrt(x) : p == 1 ? x : std::pow(x, 1 / p); }

}  // namespace

int64_t Diagram::size() const {
  int64_t n = 0;
  for (int t = 0; t < kPairTypes; ++t) n += int64_t(points[t].size() + essential[t].size());
  return n;
}

Diagram ToDiagram(const PersistenceDiagramResult& diagram, double min_persistence) {
  Diagram out;
  for (size_t k = 0; k < diagram.pairs.size(); ++k) {
    const PersistencePair& pair = diagram.pairs[k];
    const int t = pair.type;
    if (!pair.finite()) {
      out.essential[t].push_back(pair.birth_value);
      out.essential_pairs[t].push_back(int32_t(k));
    } else if (pair.Persistence() >= min_persistence) {
      out.points[t].push_back({pair.birth_value, pair.death_value});
      out.point_pairs[t].push_back(int32_t(k));
    }
  }
  return out;
}

absl::Status ValidateDistanceOptions(const DistanceOptions& options) {
  if (!(options.p >= 1) || !std::isfinite(options.p)) {
    return absl::InvalidArgumentError(
        absl::StrCat("p: ", options.p,
                     " is not a Wasserstein order; give a finite number of at least 1 (the "
                     "bottleneck distance comes with every result)"));
  }
  return absl::OkStatus();
}

Distance ComputeDistance(const Diagram& x, const Diagram& y, const DistanceOptions& options) {
  const double p = options.p;
  Distance d;
  double total = 0;
  for (int t = 0; t < kPairTypes; ++t) {
    const MatchingResult w = WassersteinMatching(x.points[t], y.points[t], p);
    double sum = Power(w.value, p);
    double largest = BottleneckMatching(x.points[t], y.points[t]).value;
    if (options.matching) {
      for (const Match& m : w.matches) {
        d.matching.push_back({int8_t(t), m.a < 0 ? -1 : x.point_pairs[t][m.a],
                              m.b < 0 ? -1 : y.point_pairs[t][m.b], m.cost});
      }
    }
    if (options.essential) {
      // Births matched in sorted order: optimal for |b1 - b2|^p on a line, p >= 1.
      std::vector<std::pair<double, int32_t>> ex, ey;
      for (size_t k = 0; k < x.essential[t].size(); ++k)
        ex.emplace_back(x.essential[t][k], x.essential_pairs[t][k]);
      for (size_t k = 0; k < y.essential[t].size(); ++k)
        ey.emplace_back(y.essential[t][k], y.essential_pairs[t][k]);
      if (ex.size() != ey.size()) {
        sum = kInf;
        largest = kInf;
      } else {
        std::sort(ex.begin(), ex.end());
        std::sort(ey.begin(), ey.end());
        for (size_t k = 0; k < ex.size(); ++k) {
          const double cost = std::abs(ex[k].first - ey[k].first);
          sum += Power(cost, p);
          largest = std::max(largest, cost);
          if (options.matching) d.matching.push_back({int8_t(t), ex[k].second, ey[k].second, cost});
        }
      }
    }
    d.wasserstein_by_type[t] = Root(sum, p);
    d.bottleneck_by_type[t] = largest;
    total += sum;
    d.bottleneck = std::max(d.bottleneck, largest);
  }
  d.wasserstein = Root(total, p);
  return d;
}

DistanceMatrix ComputeDistanceMatrix(std::span<const Diagram> diagrams,
                                     const DistanceOptions& options, const MatrixOptions& matrix) {
  DistanceMatrix out;
  const int32_t n = int32_t(diagrams.size());
  out.size = n;
  out.wasserstein.assign(size_t(n) * n, 0);
  out.bottleneck.assign(size_t(n) * n, 0);
  std::vector<std::pair<int32_t, int32_t>> entries;
  for (int32_t i = 0; i < n; ++i) {
    for (int32_t j = i + 1; j < n; ++j) entries.emplace_back(i, j);
  }
  // Largest first, so that no thread is left with a big entry at the end.
  std::stable_sort(entries.begin(), entries.end(), [&](const auto& e, const auto& f) {
    return diagrams[e.first].size() * diagrams[e.second].size() >
           diagrams[f.first].size() * diagrams[f.second].size();
  });
  const int64_t total = int64_t(entries.size());
  std::atomic<int64_t> done{0};
  std::mutex progress_mu;
  const DistanceOptions entry_options{.p = options.p, .essential = options.essential};
  ParallelFor(total, matrix.threads, [&](int64_t k, int) {
    if (matrix.stopped && matrix.stopped()) return;
    const auto [i, j] = entries[k];
    const Distance d = ComputeDistance(diagrams[i], diagrams[j], entry_options);
    out.wasserstein[size_t(i) * n + j] = out.wasserstein[size_t(j) * n + i] = d.wasserstein;
    out.bottleneck[size_t(i) * n + j] = out.bottleneck[size_t(j) * n + i] = d.bottleneck;
    const int64_t finished = done.fetch_add(1, std::memory_order_relaxed) + 1;
    if (matrix.progress) {
      std::lock_guard<std::mutex> lock(progress_mu);
      matrix.progress(finished, total);
    }
  });
  return out;
}

}  // namespace actopo::diagrams
