// Running an algorithm on C consumer threads, each with its own reader and a contiguous range of
// blocks (so each block's relations are computed by one consumer, once), or items from a shared
// queue, with progress and cancellation.
//
//   RunContext context{.consumers = 2, .progress = [](double f) { ... }};
//   absl::Status s = RunOnConsumers(context, topology, units_per_block,
//       [&](int consumer, const BlockRange& range, WorkTracker& tracker) { ... });
//
// or, for items that do not follow blocks, each consumer taking the next chunk from a queue:
//
//   absl::Status s = RunOnConsumersShared(context, saddles.size(), /*chunk=*/8,
//       [&](int consumer, ItemQueue& queue, WorkTracker& tracker) { ... });
#ifndef ACTOPO_SERVER_ALGORITHMS_CONSUMERS_H_
#define ACTOPO_SERVER_ALGORITHMS_CONSUMERS_H_

#include <algorithm>
#include <atomic>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <vector>

#include "absl/status/status.h"
#include "server/core/progress.h"
#include "server/core/topology.h"
#include "server/core/trace.h"

namespace actopo {

struct RunContext {
  int consumers = 1;
  // Fraction of the work done, in [0, 1], at most about every percent; called from consumer
  // threads, never two at once.
  std::function<void(double)> progress;
  // Set to stop the run; the algorithm returns CancelledError soon after (checked per block).
  const std::atomic<bool>* cancel = nullptr;
  // The run also stops once this passes, with DeadlineExceededError: a job's call deadline, so
  // the job stops by itself even when the server learns late that its client gave up.
  Progress::Clock::time_point deadline = Progress::Clock::time_point::max();
  // Where to record the run (trace.h): a span per consumer per parallel step ("work"), the
  // run itself ("run", category phase) and the structure's own events. Null: not recorded.
  std::shared_ptr<Trace> trace;

  // What stops the run (cancel flag and deadline), to test with stopped() or status(phase).
  Progress stop() const { return Progress({.cancel = cancel, .deadline = deadline}); }

  // The same run, for a part of it: progress reported as its place in [from, to] of this one's.
  RunContext Slice(double from, double to) const {
    RunContext part = *this;
    if (progress) {
      part.progress = [whole = progress, from, to](double f) { whole(from + (to - from) * f); };
    }
    return part;
  }
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
  // Records `units` more done; returns false when the run should stop (cancelled, or past
  // its deadline).
  bool Done(int64_t units = 1);
  bool stopped() const { return stop_.stopped(); }

 private:
  const RunContext& context_;
  const Progress stop_;
  const int64_t total_;
  std::atomic<int64_t> done_{0};
  std::atomic<int64_t> next_report_{0};
  std::mutex report_mu_;
};

// Runs body(consumer, range, tracker) on context.consumers threads (inline when 1) and returns
// CancelledError if the run was cancelled, DeadlineExceededError if its deadline passed.
absl::Status RunOnConsumers(const RunContext& context, const Topology& topology,
                            int64_t total_units,
                            const std::function<void(int, BlockRange, WorkTracker&)>& body);

// Items 0 .. n-1 handed out in ascending chunks to whichever consumer asks first: for work whose
// items vary in cost and do not follow blocks (a saddle's wall, a separatrix). Chunks are
// `chunk` items until the items left are fewer than 2 * chunk per party, then shrink to that
// share (at least 1), so the parties finish together: with fixed chunks, the last chunk of a
// gradient sweep would leave one consumer running alone at its end.
class ItemQueue {
 public:
  ItemQueue(int64_t items, int64_t chunk, int parties = 1)
      : items_(items), chunk_(std::max<int64_t>(chunk, 1)), share_(2 * std::max(parties, 1)) {}
  // The next chunk [begin, end); false when every item has been handed out.
  bool Next(int64_t& begin, int64_t& end) {
    begin = next_.load(std::memory_order_relaxed);
    int64_t size;
    do {
      if (begin >= items_) return false;
      size = std::clamp<int64_t>((items_ - begin) / share_, 1, chunk_);
    } while (!next_.compare_exchange_weak(begin, begin + size, std::memory_order_relaxed));
    end = begin + size;
    return true;
  }

 private:
  const int64_t items_, chunk_, share_;
  std::atomic<int64_t> next_{0};
};

// Runs body(consumer, queue, tracker) on context.consumers threads (inline when 1), all taking
// items from one queue of `items`; stops as RunOnConsumers does. Progress counts
// the units the bodies report to the tracker, out of `items`.
absl::Status RunOnConsumersShared(const RunContext& context, int64_t items, int64_t chunk,
                                  const std::function<void(int, ItemQueue&, WorkTracker&)>& body);

}  // namespace actopo

#endif  // ACTOPO_SERVER_ALGORITHMS_CONSUMERS_H_
