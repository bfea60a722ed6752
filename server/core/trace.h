// A Chrome trace-event recorder: where the threads of a run spend their time, as a JSON file that
// Perfetto (ui.perfetto.dev, "Open trace file") and chrome://tracing open.
//
//   Trace trace;                                   // records from now on
//   structure.SetTrace(&trace);                    // engine spans: computations, waits, evictions
//   { Trace::Scope run(&trace, "run", "phase"); ... }   // a span on this thread
//   structure.SetTrace(nullptr);                   // before the recorder goes
//   trace.WriteJson(out);
//
// Each thread appends to its own buffer (its lock is only ever contended by WriteJson), so
// recording costs two clock reads and an append per span; with a null Trace* every call site is
// one branch. Recording and WriteJson may run at the same time (late events may be left out).
// Threads are named after their role (SetThreadRole: "consumer 0", "leader 0", "worker 0.1").
// Names and categories must be string literals or other strings that outlive the recorder. At
// most `max_events` are kept (56 bytes each in memory, about 150 in the file); later ones are
// counted in dropped() and reported in the file.
#ifndef ACTOPO_SERVER_CORE_TRACE_H_
#define ACTOPO_SERVER_CORE_TRACE_H_

#include <atomic>
#include <chrono>
#include <cstdint>
#include <deque>
#include <memory>
#include <ostream>
#include <string>
#include <thread>
#include <vector>

#include "absl/base/thread_annotations.h"
#include "server/core/sync.h"

namespace actopo {

// The role of the calling thread, shown as its name in traces; kept until changed.
void SetThreadRole(std::string role);
const std::string& ThreadRole();

// Optional arguments of a trace event, shown in the trace viewer's details.
struct TraceArgs {
  int32_t block = -1;              // "block", when >= 0
  const char* relation = nullptr;  // "relation" (a two-letter code)
  int64_t count = -1;              // "count", when >= 0
};

class Trace {
 public:
  using Clock = std::chrono::steady_clock;
  static constexpr int64_t kDefaultMaxEvents = 1'000'000;

  explicit Trace(int64_t max_events = kDefaultMaxEvents);
  ~Trace();
  Trace(const Trace&) = delete;
  Trace& operator=(const Trace&) = delete;

  using Args = TraceArgs;

  // A span [start, end) on the calling thread.
  void Span(const char* name, const char* category, Clock::time_point start, Clock::time_point end,
            const Args& args = {});
  // A point in time on the calling thread.
  void Instant(const char* name, const char* category, const Args& args = {});

  // A span from construction to destruction; nothing when `trace` is null.
  class Scope {
   public:
    Scope(Trace* trace, const char* name, const char* category, const Args& args = {})
        : trace_(trace), name_(name), category_(category), args_(args) {
      if (trace_ != nullptr) start_ = Clock::now();
    }
    ~Scope() {
      if (trace_ != nullptr) trace_->Span(name_, category_, start_, Clock::now(), args_);
    }
    Scope(const Scope&) = delete;
    Scope& operator=(const Scope&) = delete;

   private:
    Trace* trace_;
    const char* name_;
    const char* category_;
    Args args_;
    Clock::time_point start_;
  };

  int64_t events() const;
  int64_t dropped() const { return dropped_.load(std::memory_order_relaxed); }

  // The trace-event JSON ({"traceEvents": [...], ...}), events in time order per thread.
  void WriteJson(std::ostream& out) const;

 private:
  struct Event {
    const char* name;
    const char* category;
    int64_t start_ns;     // since the recorder's start
    int64_t duration_ns;  // -1: an instant
    Args args;
  };
  struct ThreadBuffer {
    std::thread::id thread;
    int tid = 0;  // 1, 2, ... in order of first event
    std::string role;
    mutable Mutex mu;  // the owning thread appends, WriteJson reads
    std::deque<Event> events ABSL_GUARDED_BY(mu);
  };
  ThreadBuffer& Buffer();
  void Add(const Event& event);

  const int64_t max_events_;
  const uint64_t id_;  // tells recorders apart in the threads' caches
  const Clock::time_point origin_;
  std::atomic<int64_t> reserved_{0};
  std::atomic<int64_t> dropped_{0};
  mutable Mutex mu_ ABSL_ACQUIRED_BEFORE(ThreadBuffer::mu);
  std::vector<std::unique_ptr<ThreadBuffer>> buffers_ ABSL_GUARDED_BY(mu_);  // each: its own lock
};

}  // namespace actopo

#endif  // ACTOPO_SERVER_CORE_TRACE_H_
