// Progress reports and cancellation for long preprocessing: reading a mesh, partitioning it,
// building its static encoding, precomputing an explicit structure.
//
//   std::atomic<bool> cancel{false};
//   Progress progress({.cancel = &cancel,
//                      .deadline = Clock::now() + std::chrono::seconds(30),
//                      .report = [](std::string_view phase, double fraction) { ... }});
//   ASSIGN_OR_RETURN(auto topology, Topology::Build(mesh, blocks, {}, progress));
//
// The work calls `Update(phase, fraction)` from the thread that drives it, at points where it can
// stop (between windows of blocks, between phases): that reports and returns CANCELLED or
// DEADLINE_EXCEEDED once the work should stop, and the work returns that status, freeing what it
// built. Worker threads inside a parallel loop only test `stopped()` and skip what is left.
//
// A default Progress never stops and reports nothing: callers that need neither pass nothing.
#ifndef ACTOPO_SERVER_CORE_PROGRESS_H_
#define ACTOPO_SERVER_CORE_PROGRESS_H_

#include <atomic>
#include <chrono>
#include <functional>
#include <string>
#include <string_view>

#include "absl/status/status.h"
#include "absl/strings/str_cat.h"

namespace actopo {

class Progress {
 public:
  using Clock = std::chrono::steady_clock;
  // Called on the driving thread with the phase ("read", "partition", "encode", ...) and the
  // fraction of that phase done, in [0, 1]. It should be cheap (store and return).
  using Report = std::function<void(std::string_view phase, double fraction)>;

  struct Options {
    const std::atomic<bool>* cancel = nullptr;  // set by another thread to stop the work
    Clock::time_point deadline = Clock::time_point::max();
    Report report;
  };

  Progress() = default;
  explicit Progress(Options options) : options_(std::move(options)) {}

  // True once the work should stop (cancelled or past its deadline). Safe from any thread.
  bool stopped() const {
    return (options_.cancel != nullptr && options_.cancel->load(std::memory_order_relaxed)) ||
           (options_.deadline != Clock::time_point::max() && Clock::now() >= options_.deadline);
  }

  // OK, or why the work stops, naming the phase it stopped in.
  absl::Status status(std::string_view phase) const {
    if (options_.cancel != nullptr && options_.cancel->load(std::memory_order_relaxed)) {
      return absl::CancelledError(
          absl::StrCat("cancelled while in phase '", std::string(phase), "'"));
    }
    if (options_.deadline != Clock::time_point::max() && Clock::now() >= options_.deadline) {
      return absl::DeadlineExceededError(
          absl::StrCat("the deadline passed while in phase '", std::string(phase), "'"));
    }
    return absl::OkStatus();
  }

  // Reports `fraction` of `phase` and says whether to go on.
  absl::Status Update(std::string_view phase, double fraction) const {
    if (options_.report) options_.report(phase, fraction);
    return status(phase);
  }

  // The same stops, with `also` called after this one's report on every report.
  Progress AlsoReporting(Report also) const {
    Options options = options_;
    options.report = [first = options_.report, also = std::move(also)](std::string_view phase,
                                                                       double fraction) {
      if (first) first(phase, fraction);
      also(phase, fraction);
    };
    return Progress(std::move(options));
  }

  // The same stops, with every fraction reported as its place in [begin, end] of this one's:
  // one part of a longer phase (a series' steps each report their share of "read").
  Progress Slice(double begin, double end) const {
    Options options = options_;
    if (options_.report) {
      options.report = [first = options_.report, begin, end](std::string_view phase,
                                                             double fraction) {
        first(phase, begin + (end - begin) * fraction);
      };
    }
    return Progress(std::move(options));
  }

 private:
  Options options_;
};

}  // namespace actopo

#endif  // ACTOPO_SERVER_CORE_PROGRESS_H_
