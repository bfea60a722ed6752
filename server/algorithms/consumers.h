// Running an algorithm on C consumer threads, each with its own reader and a contiguous range of
// blocks (so each block's relations are computed by one consumer, once), with progress and
// cancellation.
//
//   RunContext context{.consumers = 2, .progress = [](double f) { ... }};
//   absl::Status s = RunOnConsumers(context, topology, units_per_block,
//       [&](int consumer, const BlockRange& range, WorkTracker& tracker) { ... });
#ifndef ACTOPO_SERVER_ALGORITHMS_CONSUMERS_H_
#define ACTOPO_SERVER_ALGORITHMS_CONSUMERS_H_

#include <atomic>
#include <cstdint>
#include <functional>
#include <mutex>
#include <vector>

#include "absl/status/status.h"
#include "server/core/topology.h"

namespace actopo {

struct RunContext {
  int consumers = 1;
  // Fraction of the work done, in [0, 1], at most about every percent; called from consumer
  // threads, never two at once.
  std::function<void(double)> progress;
  // Set to stop the run; the algorithm returns CancelledError soon after (checked per block).
  const std::atomic<bool>* cancel = nullptr;
};

struct BlockRange {
  int32_t begin = 0;
  int32_t end = 0;
};

// Splits blocks into `parts` contiguous ranges with about equal numbers of tetrahedra.
std::vector<BlockRange> SplitBlocks(const Topology& topology, int parts);

// Counts finished units of work across consumers and reports progress and cancellation.
class WorkTracker {
 public:
  WorkTracker(const RunContext& context, int64_t total_units);
  // Records `units` more done; returns false when the run is cancelled.
  bool Done(int64_t units = 1);
  bool cancelled() const {
    return context_.cancel != nullptr && context_.cancel->load(std::memory_order_relaxed);
  }

 private:
  const RunContext& context_;
  const int64_t total_;
  std::atomic<int64_t> done_{0};
  std::atomic<int64_t> next_report_{0};
  std::mutex report_mu_;
};

// Runs body(consumer, range, tracker) on context.consumers threads (inline when 1) and returns
// CancelledError if the run was cancelled.
absl::Status RunOnConsumers(const RunContext& context, const Topology& topology,
                            int64_t total_units,
                            const std::function<void(int, BlockRange, WorkTracker&)>& body);

}  // namespace actopo

#endif  // ACTOPO_SERVER_ALGORITHMS_CONSUMERS_H_
