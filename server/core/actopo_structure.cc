#include "server/core/actopo_structure.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <cstdio>
#include <cstdlib>
#include <mutex>
#include <thread>
#include <utility>

#include "absl/strings/str_cat.h"

namespace actopo {
namespace {

using Clock = std::chrono::steady_clock;

int64_t NanosSince(Clock::time_point start) {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(Clock::now() - start).count();
}

enum CellState : uint8_t { kAbsent = 0, kComputing = 1, kReady = 2, kEvicting = 3 };

// One (block, relation) of a consumer's buffer. The consumer touches it only through atomics;
// producers change it under the consumer's mutex.
struct Cell {
  std::atomic<uint8_t> state{kAbsent};
  std::atomic<int32_t> pins{0};
  std::atomic<RelationBlock*> data{nullptr};
};

struct Task {
  int32_t block;
  Relation relation;
};

// Counters written by one side and read by stats() from any thread.
struct Counter {
  std::atomic<int64_t> value{0};
  void Add(int64_t d) { value.fetch_add(d, std::memory_order_relaxed); }
  int64_t Get() const { return value.load(std::memory_order_relaxed); }
};

// Online model of this consumer's block-to-block moves: for each block, the four successors seen
// most often (space-saving counts), so the leader can prefetch where the algorithm usually goes.
class TransitionModel {
 public:
  explicit TransitionModel(int32_t blocks) : successors_(blocks) {}

  void Learn(int32_t from, int32_t to) {
    if (from < 0 || from == to) return;
    Entry* slots = successors_[from].data();
    Entry* weakest = &slots[0];
    for (int i = 0; i < kWays; ++i) {
      if (slots[i].block == to) {
        ++slots[i].count;
        return;
      }
      if (slots[i].count < weakest->count) weakest = &slots[i];
    }
    weakest->block = to;
    ++weakest->count;  // space-saving: inherits the evicted count
  }

  // Up to `limit` distinct blocks: b's likely successors, strongest first, then the chain of
  // strongest successors from the best one.
  void Predict(int32_t b, size_t limit, std::vector<int32_t>& out) const {
    out.clear();
    auto add = [&](int32_t block) {
      if (block >= 0 && block != b && out.size() < limit &&
          std::find(out.begin(), out.end(), block) == out.end()) {
        out.push_back(block);
      }
    };
    std::array<Entry, kWays> ranked = successors_[b];
    std::sort(ranked.begin(), ranked.end(),
              [](const Entry& x, const Entry& y) { return x.count > y.count; });
    for (const Entry& e : ranked) {
      if (e.count > 0) add(e.block);
    }
    int32_t current = ranked[0].count > 0 ? ranked[0].block : -1;
    for (size_t step = 0; current >= 0 && step < limit; ++step) {
      const Entry* best = nullptr;
      for (const Entry& e : successors_[current]) {
        if (e.count > 0 && (best == nullptr || e.count > best->count)) best = &e;
      }
      if (best == nullptr) break;
      add(best->block);
      current = best->block;
    }
  }

 private:
  static constexpr int kWays = 4;
  struct Entry {
    int32_t block = -1;
    int32_t count = 0;
  };
  std::vector<std::array<Entry, kWays>> successors_;
};

}  // namespace

std::string_view PrefetchName(Prefetch p) {
  switch (p) {
    case Prefetch::kLinear: return "linear";
    case Prefetch::kSpatial: return "spatial";
    case Prefetch::kAdaptive: return "adaptive";
  }
  return "?";
}

std::string_view MissPolicyName(MissPolicy p) {
  return p == MissPolicy::kLeader ? "leader" : "consumer";
}

std::string_view PrecomputeName(Precompute p) {
  return p == Precompute::kRequested ? "requested" : "declared";
}

EngineStats& EngineStats::operator+=(const EngineStats& o) {
  access += o.access;
  leader_relations += o.leader_relations;
  worker_relations += o.worker_relations;
  consumer_relations += o.consumer_relations;
  duplicates_avoided += o.duplicates_avoided;
  blocks_inserted += o.blocks_inserted;
  producer_busy_ns += o.producer_busy_ns;
  buffer_bytes += o.buffer_bytes;
  buffer_peak_bytes += o.buffer_peak_bytes;
  buffer_blocks += o.buffer_blocks;
  buffer_peak_blocks += o.buffer_peak_blocks;
  return *this;
}

// A consumer's buffer, its producers and its side of the hand-off.
class ActopoStructure::Consumer {
 public:
  Consumer(const Topology& topology, const Options& options, int capacity, int index)
      : topo_(topology),
        options_(options),
        index_(index),
        capacity_(capacity),
        window_(std::max(1, capacity / 2)),
        cells_(size_t(topology.num_blocks()) * kNumRelations),
        model_(topology.num_blocks()),
        block_inserted_(topology.num_blocks(), -1) {
    for (Relation r : AllRelations()) {
      if (options.declared.Contains(r) && !IsStatic(r)) declared_.push_back(r);
    }
  }

  ~Consumer() {
    Stop();
    for (Cell& c : cells_) delete c.data.load();
  }

  void Start() {
    producers_.emplace_back([this] {
      SetThreadRole(absl::StrCat("leader ", index_));
      LeaderLoop();
    });
    for (int w = 1; w < options_.producers; ++w) {
      producers_.emplace_back([this, w] {
        SetThreadRole(absl::StrCat("worker ", index_, ".", w));
        WorkerLoop();
      });
    }
  }

  void Stop() {
    std::lock_guard<std::mutex> lifecycle(lifecycle_mu_);  // Shutdown() and ~ may race
    {
      std::lock_guard<std::mutex> lock(mu_);
      stop_ = true;
    }
    leader_cv_.notify_all();
    worker_cv_.notify_all();
    consumer_cv_.notify_all();
    for (std::thread& t : producers_) t.join();
    producers_.clear();
  }

  bool Claim() {
    bool expected = false;
    return in_use_.compare_exchange_strong(expected, true);
  }
  void Unclaim() { in_use_.store(false); }

  Cell& cell(int32_t block, Relation r) { return cells_[size_t(block) * kNumRelations + Index(r)]; }

  void SetTrace(std::shared_ptr<Trace> trace) {
    std::lock_guard<std::mutex> lock(mu_);
    trace_ = std::move(trace);
  }

  // Consumer side: a pinned, ready cell for (block, r), or nullptr when the engine is stopping.
  Cell* Acquire(int32_t block, Relation r, int32_t previous_block) {
    requests_.Add(1);
    if (options_.prefetch == Prefetch::kAdaptive) model_.Learn(previous_block, block);
    Cell& c = cell(block, r);
    if (TryPin(c)) {
      hits_.Add(1);
      if (block == trigger_block_.load(std::memory_order_relaxed)) Hint(block, r);
      return &c;
    }
    misses_.Add(1);
    const auto start = Clock::now();
    std::unique_lock<std::mutex> lock(mu_);
    // The wait, as a span "wait" on the consumer's thread, whoever ends it.
    struct WaitSpan {
      std::shared_ptr<Trace> trace;
      Clock::time_point start;
      Trace::Args args;
      ~WaitSpan() {
        if (trace) trace->Span("wait", "consumer", start, Clock::now(), args);
      }
    } span{trace_, start, {.block = block, .relation = RelationCode(r).data()}};
    if (TryPin(c)) {  // became ready meanwhile
      wait_ns_.Add(NanosSince(start));
      return &c;
    }
    if (options_.miss_policy == MissPolicy::kConsumer && c.state.load() == kAbsent && !stop_) {
      // Compute it here: waking the leader to compute exactly this would only add a hand-off.
      // The leader still learns where the consumer is and re-targets the workers.
      c.state.store(kComputing);
      hint_ = {block, r};
      Predict(block, hint_prediction_);
      ++hint_seq_;
      leader_cv_.notify_one();
      lock.unlock();
      const auto compute_start = Clock::now();
      auto data = std::make_unique<RelationBlock>(
          ComputeBlockRelation(topo_, r, block, Scratch()));
      if (span.trace) {
        span.trace->Span(RelationCode(r).data(), "consumer", compute_start, Clock::now(),
                         span.args);
      }
      consumer_relations_.Add(1);
      lock.lock();
      Publish({block, r}, data.release());
      c.pins.fetch_add(1, std::memory_order_seq_cst);  // under mu_: no eviction in between
      wait_ns_.Add(NanosSince(start));
      return &c;
    }
    request_ = {block, r};
    Predict(block, request_prediction_);
    const uint64_t seq = ++request_seq_;
    leader_cv_.notify_one();
    consumer_cv_.wait(lock, [&] { return served_seq_ >= seq || stop_; });
    wait_ns_.Add(NanosSince(start));
    if (served_seq_ >= seq) return &c;  // the producer pinned it for us
    return nullptr;
  }

  // Any thread: switches prefetching on or off; off drops the pending tasks at once.
  void SetPrefetching(bool on) {
    std::lock_guard<std::mutex> lock(mu_);
    prefetching_ = on;
    if (!on) DropTasks();
  }

  void Unpin(Cell& c) { c.pins.fetch_sub(1, std::memory_order_seq_cst); }

  void CountOwnComputation() { consumer_relations_.Add(1); }

  EngineStats Stats() const {
    EngineStats s;
    s.access.requests = requests_.Get();
    s.access.hits = hits_.Get();
    s.access.misses = misses_.Get();
    s.access.evictions = evictions_.Get();
    s.access.wait_ns = wait_ns_.Get();
    s.leader_relations = leader_relations_.Get();
    s.worker_relations = worker_relations_.Get();
    s.consumer_relations = consumer_relations_.Get();
    s.access.relations_computed = s.leader_relations + s.worker_relations + s.consumer_relations;
    s.duplicates_avoided = duplicates_avoided_.Get();
    s.blocks_inserted = blocks_inserted_.Get();
    s.producer_busy_ns = busy_ns_.Get();
    s.buffer_bytes = bytes_.Get();
    s.buffer_peak_bytes = peak_bytes_.Get();
    s.buffer_blocks = resident_blocks_.Get();
    s.buffer_peak_blocks = peak_blocks_.Get();
    return s;
  }

 private:
  // Pins c if it is ready. Pairs with Evict(): the pin is published before the state is read
  // and eviction marks the state before reading the pins (both sequentially consistent), so a
  // consumer and an evicting producer cannot both go ahead.
  static bool TryPin(Cell& c) {
    c.pins.fetch_add(1, std::memory_order_seq_cst);
    if (c.state.load(std::memory_order_seq_cst) == kReady) return true;
    c.pins.fetch_sub(1, std::memory_order_seq_cst);
    return false;
  }

  // Consumer: the leader should re-target from here (once per prefetch window).
  void Hint(int32_t block, Relation r) {
    std::lock_guard<std::mutex> lock(mu_);
    trigger_block_.store(-1, std::memory_order_relaxed);
    hint_ = {block, r};
    Predict(block, hint_prediction_);
    ++hint_seq_;
    leader_cv_.notify_one();
  }

  // Consumer thread (reads its private model).
  void Predict(int32_t block, std::vector<int32_t>& out) {
    if (options_.prefetch == Prefetch::kAdaptive) {
      model_.Predict(block, size_t(window_), out);
    } else {
      out.clear();
    }
  }

  void LeaderLoop() {
    std::unique_lock<std::mutex> lock(mu_);
    uint64_t seen_request = 0, seen_hint = 0;
    while (true) {
      leader_cv_.wait(lock, [&] {
        return stop_ || request_seq_ > seen_request || hint_seq_ > seen_hint ||
               next_task_ < tasks_.size();
      });
      if (stop_) return;
      if (request_seq_ > seen_request) {
        seen_request = request_seq_;
        const Task request = request_;
        const std::vector<int32_t> prediction = request_prediction_;
        Serve(lock, request);
        if (stop_) return;
        Retarget(request, prediction);
      } else if (hint_seq_ > seen_hint) {
        seen_hint = hint_seq_;
        Retarget(hint_, hint_prediction_);
      } else {
        RunTask(lock, /*leader=*/true);
      }
    }
  }

  void WorkerLoop() {
    std::unique_lock<std::mutex> lock(mu_);
    while (true) {
      worker_cv_.wait(lock, [&] { return stop_ || next_task_ < tasks_.size(); });
      if (stop_) return;
      RunTask(lock, /*leader=*/false);
    }
  }

  // Leader, mu_ held: answer the consumer's miss.
  void Serve(std::unique_lock<std::mutex>& lock, const Task& request) {
    if (served_seq_ >= request_seq_) return;  // a producer's Publish() already handed it over
    Cell& c = cell(request.block, request.relation);
    switch (c.state.load()) {
      case kReady:
        HandOver(c);
        return;
      case kComputing:  // a worker is on it; its Publish() hands it over
        duplicates_avoided_.Add(1);
        return;
      default:
        Compute(lock, request, /*leader=*/true);
    }
  }

  // Producer, mu_ held: take the next useful task, if any.
  void RunTask(std::unique_lock<std::mutex>& lock, bool leader) {
    const Task task = tasks_[next_task_++];
    if (cell(task.block, task.relation).state.load() != kAbsent) {
      duplicates_avoided_.Add(1);
      return;
    }
    Compute(lock, task, leader);
  }

  // mu_ held on entry and exit; released while computing.
  void Compute(std::unique_lock<std::mutex>& lock, const Task& task, bool leader) {
    Cell& c = cell(task.block, task.relation);
    c.state.store(kComputing);
    const std::shared_ptr<Trace> trace = trace_;
    lock.unlock();
    const auto start = Clock::now();
    auto data = std::make_unique<RelationBlock>(
        ComputeBlockRelation(topo_, task.relation, task.block, Scratch()));
    const auto end = Clock::now();
    busy_ns_.Add(std::chrono::duration_cast<std::chrono::nanoseconds>(end - start).count());
    if (trace) {
      trace->Span(RelationCode(task.relation).data(), leader ? "leader" : "worker", start, end,
                  {.block = task.block});
    }
    (leader ? leader_relations_ : worker_relations_).Add(1);
    lock.lock();
    Publish(task, data.release());
  }

  static BlockScratch& Scratch() {
    thread_local BlockScratch scratch;
    return scratch;
  }

  // mu_ held: make a computed relation visible, account for it, evict if the buffer overflows,
  // and hand it to the consumer if it is waiting for exactly this.
  void Publish(const Task& task, RelationBlock* data) {
    Cell& c = cell(task.block, task.relation);
    c.data.store(data);
    c.state.store(kReady);
    AddBytes(data->bytes());
    if (block_inserted_[task.block] < 0) {
      block_inserted_[task.block] = int64_t(resident_.size());
      resident_.push_back(task.block);
      blocks_inserted_.Add(1);
      if (int64_t(resident_.size()) > peak_blocks_.Get()) {
        peak_blocks_.value.store(int64_t(resident_.size()), std::memory_order_relaxed);
      }
      if (int(resident_.size()) > capacity_) Evict(task.block);
      resident_blocks_.value.store(int64_t(resident_.size()), std::memory_order_relaxed);
    }
    if (served_seq_ < request_seq_ && request_.block == task.block &&
        request_.relation == task.relation) {
      HandOver(c);
    }
  }

  // mu_ held, c ready: pin on the consumer's behalf and wake it.
  void HandOver(Cell& c) {
    c.pins.fetch_add(1, std::memory_order_seq_cst);
    served_seq_ = request_seq_;
    consumer_cv_.notify_one();
  }

  // mu_ held: drop the oldest half of the buffer (by insertion), sparing `keep`, blocks with a
  // relation being computed and relations a consumer has pinned.
  void Evict(int32_t keep) {
    const int64_t before = evictions_.Get();
    size_t to_evict = std::max<size_t>(1, resident_.size() / 2);
    std::vector<int32_t> still;
    still.reserve(resident_.size());
    for (int32_t b : resident_) {
      if (to_evict == 0 || b == keep || !TryEvictBlock(b)) {
        still.push_back(b);
        continue;
      }
      --to_evict;
      block_inserted_[b] = -1;
      evictions_.Add(1);
    }
    resident_ = std::move(still);
    if (trace_) trace_->Instant("evict", "buffer", {.count = evictions_.Get() - before});
  }

  bool TryEvictBlock(int32_t b) {
    for (Relation r : AllRelations()) {
      if (cell(b, r).state.load() == kComputing) return false;
    }
    bool all_gone = true;
    for (Relation r : AllRelations()) {
      Cell& c = cell(b, r);
      if (c.state.load() != kReady) continue;
      c.state.store(kEvicting, std::memory_order_seq_cst);
      if (c.pins.load(std::memory_order_seq_cst) > 0) {
        c.state.store(kReady, std::memory_order_seq_cst);
        all_gone = false;
        continue;
      }
      RelationBlock* data = c.data.exchange(nullptr);
      AddBytes(-data->bytes());
      delete data;
      c.state.store(kAbsent, std::memory_order_seq_cst);
    }
    return all_gone;
  }

  void AddBytes(int64_t delta) {
    const int64_t now = bytes_.value.fetch_add(delta, std::memory_order_relaxed) + delta;
    if (now > peak_bytes_.Get()) peak_bytes_.value.store(now, std::memory_order_relaxed);
  }

  // mu_ held.
  void DropTasks() {
    tasks_.clear();
    next_task_ = 0;
    trigger_block_.store(-1, std::memory_order_relaxed);
  }

  // mu_ held: replace the workers' task list with the neighbourhood of `from`.
  void Retarget(const Task& from, const std::vector<int32_t>& prediction) {
    if (!prefetching_) {
      DropTasks();
      return;
    }
    const int32_t nb = topo_.num_blocks();
    std::vector<int32_t> blocks;
    switch (options_.prefetch) {
      case Prefetch::kLinear:
        for (int32_t d = 1; d <= window_ && from.block + d < nb; ++d) blocks.push_back(from.block + d);
        break;
      case Prefetch::kAdaptive:
        blocks = prediction;
        [[fallthrough]];
      case Prefetch::kSpatial:
        for (int32_t n : topo_.block_neighbors(from.block)) {
          if (int(blocks.size()) >= window_) break;
          if (std::find(blocks.begin(), blocks.end(), n) == blocks.end()) blocks.push_back(n);
        }
        break;
    }
    tasks_.clear();
    next_task_ = 0;
    auto add = [&](int32_t b, Relation r) {
      if (cell(b, r).state.load() == kAbsent) tasks_.push_back({b, r});
    };
    if (options_.precompute == Precompute::kDeclared) {
      for (Relation r : declared_) add(from.block, r);
    }
    for (int32_t b : blocks) {
      if (options_.precompute == Precompute::kDeclared) {
        for (Relation r : declared_) add(b, r);
      } else {
        add(b, from.relation);
      }
    }
    // Re-target again when the consumer reaches the middle of a linear window, or the first
    // (most likely) block of a spatial or learned one.
    int32_t trigger = -1;
    if (!blocks.empty()) {
      trigger = options_.prefetch == Prefetch::kLinear
                    ? blocks[std::min<size_t>(blocks.size() - 1, blocks.size() / 2)]
                    : blocks.front();
    }
    trigger_block_.store(trigger, std::memory_order_relaxed);
    if (!tasks_.empty()) worker_cv_.notify_all();
  }

  const Topology& topo_;
  const Options& options_;
  const int index_;  // of this consumer, for thread names in traces
  const int capacity_;
  const int window_;  // blocks prefetched per re-target
  std::vector<Relation> declared_;
  std::vector<Cell> cells_;
  std::atomic<bool> in_use_{false};
  std::atomic<int32_t> trigger_block_{-1};
  TransitionModel model_;  // consumer thread only

  std::mutex mu_;
  std::condition_variable leader_cv_, worker_cv_, consumer_cv_;
  // Guarded by mu_:
  bool stop_ = false;
  Task request_{-1, Relation::kVV};
  std::vector<int32_t> request_prediction_;
  uint64_t request_seq_ = 0, served_seq_ = 0;
  Task hint_{-1, Relation::kVV};
  std::vector<int32_t> hint_prediction_;
  uint64_t hint_seq_ = 0;
  std::vector<Task> tasks_;
  size_t next_task_ = 0;
  bool prefetching_ = true;  // false: re-targets drop the tasks (see SetPrefetching)
  std::shared_ptr<Trace> trace_;  // null: not recording
  std::vector<int32_t> resident_;         // blocks in the buffer, oldest first
  std::vector<int64_t> block_inserted_;   // -1 when not resident

  std::mutex lifecycle_mu_;
  std::vector<std::thread> producers_;

  Counter requests_, hits_, misses_, wait_ns_, evictions_;
  Counter leader_relations_, worker_relations_, consumer_relations_, duplicates_avoided_;
  Counter blocks_inserted_, busy_ns_, bytes_, peak_bytes_, resident_blocks_, peak_blocks_;
};

ActopoStructure::ActopoStructure(std::shared_ptr<const Topology> topology,
                                 const Options& options)
    : topology_(std::move(topology)), options_(options) {}

absl::StatusOr<std::unique_ptr<ActopoStructure>> ActopoStructure::Create(
    std::shared_ptr<const Topology> topology, const Options& options) {
  if (options.consumers < 1 || options.consumers > 256) {
    return absl::InvalidArgumentError(
        absl::StrCat("consumers: ", options.consumers, " is outside [1, 256]"));
  }
  if (options.producers < 1 || options.producers > 64) {
    return absl::InvalidArgumentError(
        absl::StrCat("producers: ", options.producers, " is outside [1, 64]"));
  }
  if (!(options.buffer_ratio >= 0.0 && options.buffer_ratio <= 1.0)) {
    return absl::InvalidArgumentError(
        absl::StrCat("buffer_ratio: ", options.buffer_ratio, " is outside [0, 1]"));
  }
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
    : ReaderBase<Reader>(topology), consumer_(consumer) {}

ActopoStructure::Reader::Reader(Reader&& other) noexcept
    : ReaderBase<Reader>(other.topology_),
      consumer_(std::exchange(other.consumer_, nullptr)),
      slots_(std::exchange(other.slots_, {})),
      own_(std::move(other.own_)),
      last_block_(other.last_block_) {}

ActopoStructure::Reader::~Reader() {
  if (consumer_ == nullptr) return;
  for (Slot& slot : slots_) Release(slot);
  consumer_->Unclaim();
}

void ActopoStructure::Reader::Release(Slot& slot) {
  if (slot.cell != nullptr) consumer_->Unpin(*static_cast<Cell*>(slot.cell));
  slot = Slot();
}

void ActopoStructure::Reader::MoveSlot(Relation r, int32_t block) {
  Slot& slot = slots_[Index(r)];
  Release(slot);
  const RelationBlock* data;
  if (Cell* c = consumer_->Acquire(block, r, last_block_)) {
    data = c->data.load(std::memory_order_acquire);
    slot.cell = c;
  } else {
    // The engine is stopping: compute it here so the algorithm still reads correct data.
    own_[Index(r)] = std::make_unique<RelationBlock>(
        ComputeBlockRelation(*topology_, r, block, *std::make_unique<BlockScratch>()));
    consumer_->CountOwnComputation();
    data = own_[Index(r)].get();
  }
  last_block_ = block;
  slot.Point(*data);
  slot.block = block;
}

}  // namespace actopo
