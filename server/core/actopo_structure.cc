#include "server/core/actopo_structure.h"

#include <pthread.h>
#include <sched.h>
#include <time.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <thread>
#include <utility>

#include "absl/base/thread_annotations.h"
#include "absl/strings/str_cat.h"
#include "server/core/relation_buffer.h"
#include "server/core/sync.h"

namespace actopo {
namespace {

using Clock = std::chrono::steady_clock;

int64_t NanosSince(Clock::time_point start) {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(Clock::now() - start).count();
}

// A statistics counter written by one side and read by stats() from any thread.
struct Counter {
  std::atomic<int64_t> value{0};
  void Add(int64_t d) { value.fetch_add(d, std::memory_order_relaxed); }
  int64_t Get() const { return value.load(std::memory_order_relaxed); }
};

// Who computes a relation: trace categories and the statistics' split.
enum class ProducerRole { kLeader, kWorker, kConsumer };

const char* RoleName(ProducerRole role) {
  switch (role) {
    case ProducerRole::kLeader: return "leader";
    case ProducerRole::kWorker: return "worker";
    case ProducerRole::kConsumer: return "consumer";
  }
  return "?";
}

// CPU time of the calling thread, in nanoseconds.
int64_t ThreadCpuNanos() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return int64_t(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
}

// Moves the calling thread to SCHED_IDLE. Lowering a thread's own priority needs no privilege;
// should the kernel refuse anyway, the thread keeps its priority, which changes only the speed.
void LowerToIdlePriority() {
  sched_param param{};
  pthread_setschedparam(pthread_self(), SCHED_IDLE, &param);
}

}  // namespace

std::string_view MissPolicyName(MissPolicy p) {
  return p == MissPolicy::kLeader ? "leader" : "consumer";
}

std::string_view ProducerPriorityName(ProducerPriority p) {
  return p == ProducerPriority::kIdle ? "idle" : "normal";
}

EngineStats& EngineStats::operator+=(const EngineStats& o) {
  access += o.access;
  leader_relations += o.leader_relations;
  worker_relations += o.worker_relations;
  consumer_relations += o.consumer_relations;
  duplicates_avoided += o.duplicates_avoided;
  waits_abandoned += o.waits_abandoned;
  blocks_inserted += o.blocks_inserted;
  producer_busy_ns += o.producer_busy_ns;
  buffer_bytes += o.buffer_bytes;
  buffer_peak_bytes += o.buffer_peak_bytes;
  buffer_blocks += o.buffer_blocks;
  buffer_peak_blocks += o.buffer_peak_blocks;
  return *this;
}

// One consumer: its buffer, its planner, its producer threads and the hand-off between them
// (the header explains the protocol, the sequence numbers and the locks).
class ActopoStructure::Consumer {
 public:
  Consumer(const Topology& topology, const Options& options, int capacity, int index)
      : topo_(topology),
        options_(options),
        index_(index),
        buffer_(topology.num_blocks(), capacity),
        planner_(topology, {.prefetch = options.prefetch,
                            .precompute = options.precompute,
                            .declared = options.declared,
                            .window = std::max(1, capacity / 2)}),
        model_(topology.num_blocks()) {}

  ~Consumer() { Stop(); }

  void Start() {
    MutexLock lifecycle(lifecycle_mu_);
    const auto spawn = [this](std::string role, void (Consumer::*loop)()) {
      return std::thread([this, role = std::move(role), loop] {
        if (options_.producer_priority == ProducerPriority::kIdle) LowerToIdlePriority();
        SetThreadRole(role);
        (this->*loop)();
      });
    };
    producers_.push_back(spawn(absl::StrCat("leader ", index_), &Consumer::LeaderLoop));
    for (int w = 1; w < options_.producers; ++w) {
      producers_.push_back(spawn(absl::StrCat("worker ", index_, ".", w), &Consumer::WorkerLoop));
    }
  }

  void Stop() {
    MutexLock lifecycle(lifecycle_mu_);
    {
      MutexLock lock(mu_);
      stop_ = true;
    }
    leader_cv_.SignalAll();
    worker_cv_.SignalAll();
    consumer_cv_.SignalAll();
    for (std::thread& t : producers_) t.join();
    producers_.clear();
  }

  bool Claim() {
    bool expected = false;
    return in_use_.compare_exchange_strong(expected, true);
  }
  void Unclaim() { in_use_.store(false); }

  void SetTrace(std::shared_ptr<Trace> trace) {
    MutexLock lock(mu_);
    trace_ = std::move(trace);
  }

  // Any thread: switches prefetching on or off; off drops the pending tasks at once.
  void SetPrefetching(bool on) {
    MutexLock lock(mu_);
    prefetching_ = on;
    if (!on) DropTasks();
  }

  // Any thread: evicts and frees what no reader pins and no one computes.
  void DropBuffered() { buffer_.EvictAll(); }

  // Consumer thread: evicts and frees `block`'s relations that nothing pins or computes.
  void Evict(int32_t block) { buffer_.Evict(block); }

  // Consumer thread: (block, r) pinned for the caller, or null when the engine is stopping.
  // A computation on the consumer's thread uses the reader's `scratch`.
  const RelationBlock* Acquire(int32_t block, Relation r, int32_t previous_block,
                               BlockScratch& scratch) {
    requests_.Add(1);
    if (options_.prefetch == Prefetch::kAdaptive) model_.Learn(previous_block, block);
    if (const RelationBlock* data = buffer_.TryPin(block, r)) {
      hits_.Add(1);
      if (block == trigger_block_.load(std::memory_order_relaxed) && planner_.Follows(r)) {
        Hint(block, r);
      }
      return data;
    }
    misses_.Add(1);
    return Miss(block, r, scratch);
  }

  void Unpin(int32_t block, Relation r) { buffer_.Unpin(block, r); }

  // Consumer thread: (block, r) for the reader alone, outside the buffer (the engine stopping,
  // or a producer at idle priority computing it too slowly). Counted and traced as the
  // consumer's computation, its time as the consumer's wait.
  std::unique_ptr<RelationBlock> ComputeOwnCopy(int32_t block, Relation r, BlockScratch& scratch) {
    std::shared_ptr<Trace> trace;
    {
      MutexLock lock(mu_);
      trace = trace_;
    }
    const auto start = Clock::now();
    auto data = std::make_unique<RelationBlock>(ComputeBlockRelation(topo_, r, block, scratch));
    const auto end = Clock::now();
    consumer_relations_.Add(1);
    wait_ns_.Add(std::chrono::duration_cast<std::chrono::nanoseconds>(end - start).count());
    if (trace) {
      trace->Span(RelationCode(r).data(), RoleName(ProducerRole::kConsumer), start, end,
                  {.block = block});
    }
    return data;
  }

  EngineStats Stats() const {
    const RelationBuffer::Stats b = buffer_.stats();
    EngineStats s;
    s.access.requests = requests_.Get();
    s.access.hits = hits_.Get();
    s.access.misses = misses_.Get();
    s.access.evictions = b.evictions;
    s.access.wait_ns = wait_ns_.Get();
    s.leader_relations = leader_relations_.Get();
    s.worker_relations = worker_relations_.Get();
    s.consumer_relations = consumer_relations_.Get();
    s.access.relations_computed = s.leader_relations + s.worker_relations + s.consumer_relations;
    s.duplicates_avoided = duplicates_avoided_.Get();
    s.waits_abandoned = waits_abandoned_.Get();
    s.blocks_inserted = b.blocks_inserted;
    s.producer_busy_ns = busy_ns_.Get();
    s.buffer_bytes = b.bytes;
    s.buffer_peak_bytes = b.peak_bytes;
    s.buffer_blocks = b.blocks;
    s.buffer_peak_blocks = b.peak_blocks;
    return s;
  }

 private:
  // The consumer's wait on a miss, recorded as a span "wait" on its thread whoever ends it.
  struct WaitSpan {
    std::shared_ptr<Trace> trace;
    Clock::time_point start;
    Trace::Args args;
    ~WaitSpan() {
      if (trace) trace->Span("wait", "consumer", start, Clock::now(), args);
    }
  };

  // Consumer thread, (block, r) not ready at the lock-free look.
  const RelationBlock* Miss(int32_t block, Relation r, BlockScratch& scratch) {
    const auto start = Clock::now();
    MutexLock lock(mu_);
    WaitSpan span{trace_, start, {.block = block, .relation = RelationCode(r).data()}};
    if (const RelationBlock* data = buffer_.TryPin(block, r)) {  // became ready meanwhile
      wait_ns_.Add(NanosSince(start));
      return data;
    }
    if (options_.miss_policy == MissPolicy::kConsumer && !stop_ &&
        buffer_.StartComputing(block, r)) {
      // Compute it here: waking the leader to compute exactly this would only add a hand-off.
      // The leader still learns where the consumer is and re-plans.
      if (planner_.Follows(r)) PostHint(block, r);
      const RelationBlock* data =
          Compute({block, r}, ProducerRole::kConsumer, /*pin=*/true, scratch);
      wait_ns_.Add(NanosSince(start));
      return data;
    }
    request_ = {block, r};
    Predict(block, request_prediction_);
    const uint64_t seq = ++request_seq_;
    leader_cv_.Signal();
    if (options_.producer_priority != ProducerPriority::kIdle) {
      while (served_seq_ < seq && !stop_) consumer_cv_.Wait(mu_);
    } else {
      // A producer at idle priority gets no cycles while other threads hold every core (other
      // sessions, other processes), so the consumer waits only as long as the computation
      // takes, then computes the relation itself; without this, a run beside busy threads would
      // wait on producers that never get a core.
      const Clock::time_point give_up = start + Patience(r);
      while (served_seq_ < seq && !stop_ && Clock::now() < give_up) {
        consumer_cv_.WaitFor(mu_, give_up - Clock::now());
      }
      if (served_seq_ < seq && !stop_) {
        served_seq_ = seq;  // withdrawn: nobody hands it over now
        waits_abandoned_.Add(1);
        if (buffer_.StartComputing(block, r)) {  // the leader has not started on it
          const RelationBlock* data =
              Compute({block, r}, ProducerRole::kConsumer, /*pin=*/true, scratch);
          wait_ns_.Add(NanosSince(start));
          return data;
        }
        wait_ns_.Add(NanosSince(start));
        return nullptr;  // a producer is computing it: the reader computes its own copy
      }
    }
    wait_ns_.Add(NanosSince(start));
    return served_seq_ >= seq ? handed_over_ : nullptr;
  }

  // How long a consumer waits for a producer at idle priority: the mean CPU time computations
  // of r have taken in this consumer's engine so far (of any relation before the first of r).
  // A producer that runs finishes within it, having started first. CPU time, not wall time: a
  // producer the scheduler starved took long on the clock, and counting that would make every
  // later wait longer just when the machine is busy.
  Clock::duration Patience(Relation r) const {
    int64_t ns = compute_cpu_ns_[Index(r)].Get(), count = computed_[Index(r)].Get();
    if (count == 0) {
      for (Relation other : AllRelations()) {
        ns += compute_cpu_ns_[Index(other)].Get();
        count += computed_[Index(other)].Get();
      }
    }
    if (count == 0) return std::chrono::milliseconds(1);  // the first computation: a block's
    return std::chrono::nanoseconds(ns / count);
  }

  // Consumer thread: it reached the plan's trigger block; the leader should re-plan from here.
  void Hint(int32_t block, Relation r) {
    MutexLock lock(mu_);
    PostHint(block, r);
  }

  void PostHint(int32_t block, Relation r) ABSL_EXCLUSIVE_LOCKS_REQUIRED(mu_) {
    trigger_block_.store(-1, std::memory_order_relaxed);
    hint_ = {block, r};
    Predict(block, hint_prediction_);
    ++hint_seq_;
    leader_cv_.Signal();
  }

  // Consumer thread (the model is its own).
  void Predict(int32_t block, std::vector<int32_t>& out) ABSL_EXCLUSIVE_LOCKS_REQUIRED(mu_) {
    out.clear();
    if (options_.prefetch == Prefetch::kAdaptive) {
      model_.Predict(block, size_t(planner_.options().window), out);
    }
  }

  // A producer's scratch lives as long as its thread, which the engine joins when it stops.
  void LeaderLoop() {
    BlockScratch scratch;
    MutexLock lock(mu_);
    uint64_t seen_request = 0, seen_hint = 0;
    while (true) {
      while (!stop_ && request_seq_ == seen_request && hint_seq_ == seen_hint &&
             next_task_ >= plan_.tasks.size()) {
        leader_cv_.Wait(mu_);
      }
      if (stop_) return;
      if (request_seq_ != seen_request) {
        seen_request = request_seq_;
        const BlockTask request = request_;
        const std::vector<int32_t> prediction = request_prediction_;
        Serve(request, scratch);
        if (stop_) return;
        if (planner_.Follows(request.relation)) Replan(request, prediction);
      } else if (hint_seq_ != seen_hint) {
        seen_hint = hint_seq_;
        Replan(hint_, hint_prediction_);
      } else {
        RunTask(ProducerRole::kLeader, scratch);
      }
    }
  }

  void WorkerLoop() {
    BlockScratch scratch;
    MutexLock lock(mu_);
    while (true) {
      while (!stop_ && next_task_ >= plan_.tasks.size()) worker_cv_.Wait(mu_);
      if (stop_) return;
      RunTask(ProducerRole::kWorker, scratch);
    }
  }

  // Leader: answer the consumer's pending miss.
  void Serve(const BlockTask& request, BlockScratch& scratch) ABSL_EXCLUSIVE_LOCKS_REQUIRED(mu_) {
    if (served_seq_ >= request_seq_) return;  // a producer's Publish already handed it over
    if (const RelationBlock* data = buffer_.TryPin(request.block, request.relation)) {
      HandOver(data);
    } else if (buffer_.StartComputing(request.block, request.relation)) {
      Compute(request, ProducerRole::kLeader, /*pin=*/false, scratch);
    } else {
      duplicates_avoided_.Add(1);  // a worker is on it; its Publish hands it over
    }
  }

  // Producer: take the next planned task; skip it if it is computing or there already.
  void RunTask(ProducerRole role, BlockScratch& scratch) ABSL_EXCLUSIVE_LOCKS_REQUIRED(mu_) {
    const BlockTask task = plan_.tasks[next_task_++];
    if (!buffer_.StartComputing(task.block, task.relation)) {
      duplicates_avoided_.Add(1);
      return;
    }
    Compute(task, role, /*pin=*/false, scratch);
  }

  // (task) was moved to computing by this thread: compute it with mu_ released, publish it,
  // and hand it to the consumer if it waits for exactly this. Returns the data, pinned if `pin`.
  // `scratch` is the computing thread's.
  const RelationBlock* Compute(const BlockTask& task, ProducerRole role, bool pin,
                               BlockScratch& scratch) ABSL_EXCLUSIVE_LOCKS_REQUIRED(mu_) {
    const std::shared_ptr<Trace> trace = trace_;
    mu_.Unlock();
    if (role != ProducerRole::kConsumer && options_.before_producer_computes) {
      options_.before_producer_computes(task.block, task.relation);
    }
    const auto start = Clock::now();
    const int64_t cpu_start = ThreadCpuNanos();
    auto data = std::make_unique<RelationBlock>(
        ComputeBlockRelation(topo_, task.relation, task.block, scratch));
    compute_cpu_ns_[Index(task.relation)].Add(ThreadCpuNanos() - cpu_start);
    const auto end = Clock::now();
    const RelationBlock* published = data.get();
    const int64_t ns = std::chrono::duration_cast<std::chrono::nanoseconds>(end - start).count();
    if (role != ProducerRole::kConsumer) busy_ns_.Add(ns);
    computed_[Index(task.relation)].Add(1);
    mu_.Lock();
    RelationBuffer::Evicted evicted =
        buffer_.Publish(task.block, task.relation, std::move(data), pin);
    // Counted (and traced) once published: whoever sees the count sees the block in the
    // buffer (the prefetch test waits on the leader's count before reading the next block).
    switch (role) {
      case ProducerRole::kLeader: leader_relations_.Add(1); break;
      case ProducerRole::kWorker: worker_relations_.Add(1); break;
      case ProducerRole::kConsumer: consumer_relations_.Add(1); break;
    }
    if (trace) {
      trace->Span(RelationCode(task.relation).data(), RoleName(role), start, end,
                  {.block = task.block});
    }
    if (evicted.blocks > 0 && trace_) {
      trace_->Instant("evict", "buffer", {.count = evicted.blocks});
    }
    if (served_seq_ < request_seq_ && request_.block == task.block &&
        request_.relation == task.relation) {
      HandOver(buffer_.TryPin(task.block, task.relation));
    }
    if (!evicted.data.empty()) {
      // Freed without mu_: the consumer may need it meanwhile, and a producer at idle priority
      // can be descheduled for long while it returns megabytes to the system.
      mu_.Unlock();
      evicted.data.clear();
      mu_.Lock();
    }
    return published;
  }

  // The consumer's pending request is ready and pinned for it: wake it.
  void HandOver(const RelationBlock* data) ABSL_EXCLUSIVE_LOCKS_REQUIRED(mu_) {
    handed_over_ = data;
    served_seq_ = request_seq_;
    consumer_cv_.Signal();
  }

  void DropTasks() ABSL_EXCLUSIVE_LOCKS_REQUIRED(mu_) {
    plan_.tasks.clear();
    next_task_ = 0;
    trigger_block_.store(-1, std::memory_order_relaxed);
  }

  // Leader: replace the producers' tasks with a plan from the consumer's position.
  void Replan(const BlockTask& from, const std::vector<int32_t>& prediction)
      ABSL_EXCLUSIVE_LOCKS_REQUIRED(mu_) {
    if (!prefetching_) {
      DropTasks();
      return;
    }
    planner_.Make(
        from, prediction,
        [&](int32_t b, Relation r) {
          return buffer_.state(b, r) == RelationBuffer::State::kAbsent;
        },
        plan_);
    next_task_ = 0;
    trigger_block_.store(plan_.trigger_block, std::memory_order_relaxed);
    if (!plan_.tasks.empty()) worker_cv_.SignalAll();
  }

  const Topology& topo_;
  const Options& options_;
  const int index_;  // of this consumer, for thread names in traces
  RelationBuffer buffer_;
  const PrefetchPlanner planner_;
  TransitionModel model_;  // consumer thread only
  std::atomic<bool> in_use_{false};
  std::atomic<int32_t> trigger_block_{-1};  // the current plan's, -1 once hinted or dropped

  Mutex lifecycle_mu_ ABSL_ACQUIRED_BEFORE(mu_);
  std::vector<std::thread> producers_ ABSL_GUARDED_BY(lifecycle_mu_);

  Mutex mu_;
  CondVar leader_cv_;    // a request, a hint or a task for the leader; stop
  CondVar worker_cv_;    // tasks; stop
  CondVar consumer_cv_;  // the request served; stop
  bool stop_ ABSL_GUARDED_BY(mu_) = false;
  BlockTask request_ ABSL_GUARDED_BY(mu_);
  std::vector<int32_t> request_prediction_ ABSL_GUARDED_BY(mu_);
  uint64_t request_seq_ ABSL_GUARDED_BY(mu_) = 0;
  uint64_t served_seq_ ABSL_GUARDED_BY(mu_) = 0;
  const RelationBlock* handed_over_ ABSL_GUARDED_BY(mu_) = nullptr;  // pinned for the consumer
  BlockTask hint_ ABSL_GUARDED_BY(mu_);
  std::vector<int32_t> hint_prediction_ ABSL_GUARDED_BY(mu_);
  uint64_t hint_seq_ ABSL_GUARDED_BY(mu_) = 0;
  PrefetchPlanner::Plan plan_ ABSL_GUARDED_BY(mu_);
  size_t next_task_ ABSL_GUARDED_BY(mu_) = 0;
  bool prefetching_ ABSL_GUARDED_BY(mu_) = true;       // false: re-plans drop the tasks
  std::shared_ptr<Trace> trace_ ABSL_GUARDED_BY(mu_);  // null: not recording

  Counter requests_, hits_, misses_, wait_ns_;
  Counter leader_relations_, worker_relations_, consumer_relations_, duplicates_avoided_;
  Counter busy_ns_, waits_abandoned_;
  // Per relation: CPU time spent computing it and how many times, by anyone (Patience).
  std::array<Counter, kNumRelations> compute_cpu_ns_, computed_;
};

ActopoStructure::ActopoStructure(std::shared_ptr<const Topology> topology, const Options& options)
    : topology_(std::move(topology)), options_(options) {}

absl::Status ActopoStructure::Validate(const Options& options) {
  if (options.consumers < 1 || options.consumers > kMaxConsumers) {
    return absl::InvalidArgumentError(
        absl::StrCat("consumers: ", options.consumers, " is outside [1, ", kMaxConsumers, "]"));
  }
  if (options.producers < 1 || options.producers > kMaxProducers) {
    return absl::InvalidArgumentError(
        absl::StrCat("producers: ", options.producers, " is outside [1, ", kMaxProducers, "]"));
  }
  if (!(options.buffer_ratio >= 0.0 && options.buffer_ratio <= 1.0)) {
    return absl::InvalidArgumentError(
        absl::StrCat("buffer_ratio: ", options.buffer_ratio, " is outside [0, 1]"));
  }
  return absl::OkStatus();
}

absl::StatusOr<std::unique_ptr<ActopoStructure>> ActopoStructure::Create(
    std::shared_ptr<const Topology> topology, const Options& options) {
  if (absl::Status status = Validate(options); !status.ok()) return status;
  auto s = std::unique_ptr<ActopoStructure>(new ActopoStructure(std::move(topology), options));
  s->capacity_ = static_cast<int>(std::floor(options.buffer_ratio * s->topology_->num_blocks() /
                                             options.consumers)) +
                 1;
  for (int c = 0; c < options.consumers; ++c) {
    s->consumers_.push_back(
        std::make_unique<Consumer>(*s->topology_, s->options_, s->capacity_, c));
  }
  // Configuration is complete: only now do threads start.
  for (auto& c : s->consumers_) c->Start();
  return s;
}

ActopoStructure::~ActopoStructure() { Shutdown(); }

void ActopoStructure::Shutdown() {
  for (auto& c : consumers_) c->Stop();
}

void ActopoStructure::SetPrefetching(bool on) {
  for (auto& c : consumers_) c->SetPrefetching(on);
}

void ActopoStructure::DropBufferedRelations() {
  for (auto& c : consumers_) c->DropBuffered();
}

void ActopoStructure::SetTrace(std::shared_ptr<Trace> trace) {
  for (auto& c : consumers_) c->SetTrace(trace);
}

ActopoStructure::Reader ActopoStructure::NewReader() {
  for (auto& c : consumers_) {
    if (c->Claim()) return Reader(topology_.get(), c.get());
  }
  std::fprintf(stderr, "actopo: more than %d readers at once on an actopo structure\n",
               options_.consumers);
  std::abort();
}

std::vector<EngineStats> ActopoStructure::consumer_stats() const {
  std::vector<EngineStats> out;
  for (const auto& c : consumers_) out.push_back(c->Stats());
  return out;
}

EngineStats ActopoStructure::stats() const {
  EngineStats total;
  for (const auto& c : consumers_) total += c->Stats();
  return total;
}

MemoryStats ActopoStructure::memory() const {
  const EngineStats s = stats();
  MemoryStats m;
  m.static_bytes = topology_->bytes().total();
  m.relation_bytes = s.buffer_bytes;
  m.relation_peak_bytes = s.buffer_peak_bytes;
  return m;
}

ActopoStructure::Reader::Reader(const Topology* topology, Consumer* consumer)
    : BlockSlotReader<Reader, Slot>(topology, {}), consumer_(consumer) {}

ActopoStructure::Reader::Reader(Reader&& other) noexcept
    : BlockSlotReader<Reader, Slot>(other.topology_, std::exchange(other.slots_, {})),
      consumer_(std::exchange(other.consumer_, nullptr)),
      own_(std::move(other.own_)),
      scratch_(std::move(other.scratch_)),
      last_block_(other.last_block_) {}

ActopoStructure::Reader::~Reader() {
  if (consumer_ == nullptr) return;
  for (Relation r : AllRelations()) Release(r);
  consumer_->Unclaim();
}

void ActopoStructure::Reader::Release(Relation r) {
  Slot& slot = slots_[Index(r)];
  if (slot.pinned) consumer_->Unpin(slot.block, r);
  slot = Slot();
}

void ActopoStructure::Reader::Finished(int32_t block) {
  for (Relation r : AllRelations()) {
    if (slots_[Index(r)].block != block) continue;
    const bool own = !slots_[Index(r)].pinned;
    Release(r);
    if (own) own_[Index(r)].reset();
  }
  consumer_->Evict(block);
}

void ActopoStructure::Reader::MoveSlot(Relation r, int32_t block) {
  Release(r);
  Slot& slot = slots_[Index(r)];
  const RelationBlock* data = consumer_->Acquire(block, r, last_block_, scratch_);
  if (data != nullptr) {
    slot.pinned = true;
  } else {
    // The engine is stopping, or a producer at idle priority is computing it too slowly:
    // compute it here so the algorithm reads correct data at once.
    own_[Index(r)] = consumer_->ComputeOwnCopy(block, r, scratch_);
    data = own_[Index(r)].get();
  }
  last_block_ = block;
  slot.Point(*data);
  slot.block = block;
}

}  // namespace actopo
