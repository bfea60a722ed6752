#include "server/algorithms/consumers.h"

#include <algorithm>
#include <thread>

#include "absl/strings/str_cat.h"

namespace actopo {

std::vector<BlockRange> SplitBlocks(const Topology& topology, int parts) {
  const int32_t nb = topology.num_blocks();
  parts = std::clamp(parts, 1, std::max(nb, 1));
  const int64_t total = topology.num_tetrahedra();
  std::vector<BlockRange> ranges;
  int32_t begin = 0;
  for (int p = 0; p < parts; ++p) {
    int32_t end = begin;
    if (p == parts - 1) {
      end = nb;
    } else {
      const int64_t target = total * (p + 1) / parts;
      // Leave at least one block for each remaining part.
      while (end < nb - (parts - 1 - p) &&
             (end == begin || topology.block_tetrahedron_begin(end + 1) <= target)) {
        ++end;
      }
    }
    ranges.push_back({begin, end});
    begin = end;
  }
  return ranges;
}

WorkTracker::WorkTracker(const RunContext& context, int64_t total_units)
    : context_(context), stop_(context.stop()), total_(std::max<int64_t>(total_units, 1)) {}

bool WorkTracker::Done(int64_t units) {
  const int64_t done = done_.fetch_add(units, std::memory_order_relaxed) + units;
  if (context_.progress && done >= next_report_.load(std::memory_order_relaxed)) {
    std::lock_guard<std::mutex> lock(report_mu_);
    if (done >= next_report_.load(std::memory_order_relaxed)) {
      next_report_.store(done + std::max<int64_t>(total_ / 100, 1), std::memory_order_relaxed);
      context_.progress(std::min(1.0, double(done) / double(total_)));
    }
  }
  return !stopped();
}

namespace {

// Runs fn(c) for c in [0, n) on n threads, or inline when n is 1; then the run's status.
absl::Status RunThreads(int n, const WorkTracker& tracker, const RunContext& context,
                        const std::function<void(int)>& fn) {
  const auto traced = [&](int c) {
    Trace::Scope span(context.trace.get(), "work", "consumer");
    fn(c);
  };
  if (n == 1) {
    traced(0);
  } else {
    std::vector<std::thread> threads;
    for (int c = 0; c < n; ++c) {
      threads.emplace_back([&, c] {
        SetThreadRole(absl::StrCat("consumer ", c));
        traced(c);
      });
    }
    for (std::thread& t : threads) t.join();
  }
  if (tracker.stopped()) return context.stop().status("run");
  if (context.progress) context.progress(1.0);
  return absl::OkStatus();
}

}  // namespace

absl::Status RunOnConsumers(const RunContext& context, const Topology& topology,
                            int64_t total_units,
                            const std::function<void(int, BlockRange, WorkTracker&)>& body) {
  WorkTracker tracker(context, total_units);
  const std::vector<BlockRange> ranges = SplitBlocks(topology, context.consumers);
  return RunThreads(int(ranges.size()), tracker, context,
                    [&](int c) { body(c, ranges[c], tracker); });
}

absl::Status RunOnConsumersShared(const RunContext& context, int64_t items, int64_t chunk,
                                  const std::function<void(int, ItemQueue&, WorkTracker&)>& body) {
  WorkTracker tracker(context, items);
  ItemQueue queue(items, chunk, std::max(context.consumers, 1));
  return RunThreads(std::max(context.consumers, 1), tracker, context,
                    [&](int c) { body(c, queue, tracker); });
}

}  // namespace actopo
