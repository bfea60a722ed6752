// The ACTOPO task-parallel structure (Liu & Iuricich, "A Task-Parallel Approach for Localized
// Topological Data Structures"): the algorithm's consumer threads read block relations from a
// bounded buffer that producer threads fill ahead of need.
//
//   ActopoStructure::Options options{.consumers = 1, .producers = 2,
//                                    .prefetch = Prefetch::kLinear,
//                                    .precompute = Precompute::kRequested};
//   ASSIGN_OR_RETURN(auto structure, ActopoStructure::Create(topology, options));
//   auto reader = structure->NewReader();          // one per consumer thread
//   for (SimplexId t : reader.vertex_star(v)) ...
//
// Per consumer: its own buffer of floor(buffer_ratio * blocks / consumers) + 1 blocks and its own
// P producers. On a miss, the leader re-targets the workers to the neighbourhood of the missed
// block; workers compute (block, relation) pairs speculatively. The missed relation itself is
// computed at once, by the leader (MissPolicy::kLeader, the paper's protocol: the consumer waits
// for the hand-off) or by the consumer (kConsumer, the default: no thread hand-off to wait for,
// faster on topo-relations and Morse-Smale, see bench/RESULTS.md); either way never twice at once.
// While no request is pending the leader prefetches too (one task at a time, so a new request
// waits at most one block computation): when the consumer reads faster than one producer
// computes, which is the common case, an idle leader would waste a core.
//
// The engine in one consumer (actopo_structure.cc; C consumers share nothing but the Topology):
//
//   consumer thread (the algorithm's)     producers: 1 leader + P-1 workers
//   Reader::Lookup ---------------------> RelationBuffer (relation_buffer.h): per (block,
//     hit: TryPin, lock-free                relation) absent -> computing -> ready -> absent,
//     miss: Acquire() under mu_             pins, eviction of the oldest half
//   posts a request or a hint ----------> leader: serves the request, then asks the
//                                           PrefetchPlanner (prefetch_planner.h) for the next
//                                           tasks; workers (and an idle leader) take them
//
// State per (block, relation): see relation_buffer.h. Who moves it here: StartComputing by the
// one producer or consumer that will compute it (whoever wins the compare-and-swap; the others
// count a duplicate avoided), Publish by that thread, eviction inside Publish. So nothing is
// computed twice at once, and a relation is freed only when no reader holds a pin on it.
//
// Sequence numbers (all under the consumer's mu_, each only ever grows):
// - request_seq: the consumer posts a miss it waits for (kLeader policy, or the relation is
//   being computed by a producer); served_seq catches up to it once that relation is pinned for
//   the consumer, by the leader (it was ready, or the leader computed it) or by the Publish of
//   whoever computed it. The consumer waits until served_seq >= its request's number.
// - hint_seq: the consumer tells the leader where it is without waiting (it reached the trigger
//   block of the current plan, or computes a miss itself under kConsumer), on the relations
//   the plan follows (PrefetchPlanner::Follows: not critical points' VB, read wherever a
//   boundary vertex's neighbours lie). A request on another relation is served, not planned from.
//   The leader keeps the last request and hint numbers it has handled and re-plans once per new
//   one.
//
// Locks, in the order they nest (a thread holding one takes only locks listed below it):
//   lifecycle_mu  Start/Stop of the producer threads (Shutdown and the destructor may race).
//   mu            one per consumer: stop flag, request/hint/served numbers and their payloads,
//                 the current plan and its cursor, the prefetching switch, the trace pointer.
//                 Producers hold it except while computing a relation or freeing what an
//                 eviction returned; the consumer takes it only on a miss and once per plan (a
//                 hint).
//   buffer mu     inside RelationBuffer::Publish only: the resident list (evicted data is
//                 handed back and freed after both locks are released).
// Lock-free: pins and states (RelationBuffer), the trigger block, statistics counters, and the
// TransitionModel of the adaptive mode (consumer thread only). Members are annotated with
// Abseil's thread-safety attributes and checked by clang -Wthread-safety (make
// test-thread-safety).
//
// Guarantees beyond the reference code: nothing computed twice at once (but see
// ProducerPriority::kIdle) and an empty relation is "ready" (the state above); producers sleep on
// condition variables when there is nothing to do; eviction never frees a relation a consumer is
// reading (pins); the configuration is fixed before any thread starts; destruction and Shutdown
// stop and join every producer, also while a consumer waits on a miss (that consumer then computes
// the relation itself, so its results stay correct).
//
// A read inside the block a reader is already on is a comparison; moving to another block is a
// few atomic operations on a hit.
#ifndef ACTOPO_SERVER_CORE_ACTOPO_STRUCTURE_H_
#define ACTOPO_SERVER_CORE_ACTOPO_STRUCTURE_H_

#include <array>
#include <atomic>
#include <cstdint>
#include <functional>
#include <memory>
#include <string_view>
#include <vector>

#include "absl/status/statusor.h"
#include "server/core/block_relations.h"
#include "server/core/prefetch_planner.h"
#include "server/core/relation.h"
#include "server/core/stats.h"
#include "server/core/structure.h"
#include "server/core/topology.h"
#include "server/core/trace.h"

namespace actopo {

// Who computes a relation the consumer misses when no producer is already computing it.
enum class MissPolicy : uint8_t {
  kLeader,    // the paper's protocol: the consumer asks its leader and waits
  kConsumer,  // the consumer computes it itself (no thread hand-off) and only tells the leader
              // where it is, so the workers re-target
};

std::string_view MissPolicyName(MissPolicy p);

// The CPU priority of the producer threads. A producer's work is speculative: when every core
// runs a consumer, a producer at normal priority takes its cycles from a consumer, and the
// relations it prefetches are ones that consumer would have computed anyway, so the run takes
// longer than without producers. At idle priority (Linux's SCHED_IDLE) a producer runs only on a
// core no consumer wants: while its consumer waits, in a phase with fewer consumers than cores,
// or on a machine with cores to spare.
// While other threads hold every core (other sessions' consumers, other processes) it gets
// almost no cycles, so a consumer whose miss such a producer is computing waits only as long as
// a computation of that relation takes (its mean CPU time so far), then computes its own copy
// (EngineStats::waits_abandoned): the one case where a relation is computed twice at once.
enum class ProducerPriority : uint8_t {
  kNormal,  // the consumers' priority: producers compete with them for the cores
  kIdle,    // SCHED_IDLE: producers use only cycles no other thread wants
};

std::string_view ProducerPriorityName(ProducerPriority p);

// Engine counters of one consumer (and summed per session).
struct EngineStats {
  AccessStats access;
  int64_t leader_relations = 0;    // (block, relation) computed by leaders
  int64_t worker_relations = 0;    // ... by workers
  int64_t consumer_relations = 0;  // ... by consumers (their misses under kConsumer, and
                                   // every miss once the engine is stopping)
  int64_t duplicates_avoided = 0;  // tasks skipped because already computing or ready
  // Misses the consumer computed itself after waiting as long as a computation takes for a
  // producer at idle priority (ProducerPriority::kIdle), which gets no cycles on busy cores.
  int64_t waits_abandoned = 0;
  int64_t blocks_inserted = 0;   // blocks that entered the buffer
  int64_t producer_busy_ns = 0;  // time producers spent computing
  int64_t buffer_bytes = 0;      // now
  int64_t buffer_peak_bytes = 0;
  int64_t buffer_blocks = 0;  // resident blocks now
  // At most capacity + 1 + blocks pinned by the consumer + blocks with a relation being
  // computed (eviction spares both; one computation per producer and per consumer at a time).
  int64_t buffer_peak_blocks = 0;

  EngineStats& operator+=(const EngineStats& o);
};

class ActopoStructure {
 public:
  struct Options {
    int consumers = 1;
    int producers = 1;  // per consumer: 1 leader + (producers - 1) workers
    double buffer_ratio = 0.2;
    Prefetch prefetch = Prefetch::kLinear;
    Precompute precompute = Precompute::kRequested;
    RelationSet declared = RelationSet::All();       // used by Precompute::kDeclared
    MissPolicy miss_policy = MissPolicy::kConsumer;  // the faster; kLeader: the paper
    ProducerPriority producer_priority = ProducerPriority::kNormal;
    // Tests only: called by a producer before each computation, outside every lock (a test
    // holds a producer there to stand for one that gets no cycles).
    std::function<void(int32_t block, Relation r)> before_producer_computes;
  };
  // The ranges Validate enforces: consumers and producers in [1, 64], buffer_ratio in [0, 1].
  static constexpr int kMaxConsumers = 64;
  static constexpr int kMaxProducers = 64;

  // INVALID_ARGUMENT naming the option and its value ("consumers: 300 is outside [1, 64]").
  static absl::Status Validate(const Options& options);

  // Validates the options and starts C * P threads.
  static absl::StatusOr<std::unique_ptr<ActopoStructure>> Create(
      std::shared_ptr<const Topology> topology, const Options& options);
  ~ActopoStructure();  // stops and joins every producer; readers must be gone

  // Stops and joins every producer now (e.g. on cancellation). Readers stay usable: what they
  // miss from then on they compute themselves. Idempotent.
  void Shutdown();

  // Off: producers stop prefetching (pending tasks dropped, re-targets ignored) and only a
  // missed relation is still computed, by whoever the miss policy names; on again: the next
  // miss or hint re-targets them. For phases that read blocks in no order an engine could
  // follow (Morse-Smale's walls): prefetching there computes blocks nobody reads, on the
  // consumers' cores, and evicts the ones they come back to. Safe to call while running.
  void SetPrefetching(bool on);

  // Drops every buffered relation no reader pins (or producer computes): between phases of an
  // algorithm, when the blocks the last phase kept (the end of its sweep, and relations the next
  // phase does not read) would only stand beside the next phase's own arrays (EndPhase in
  // server/algorithms/prefetch_off.h also returns the memory to the system). Safe to call while
  // running.
  void DropBufferedRelations();

  // Records into `trace` from now on (null: stop): per thread, spans for every (block,
  // relation) computed (named by the relation's code, category leader, worker or consumer),
  // every consumer wait on a miss ("wait", category consumer), and an instant per eviction
  // ("evict", category buffer, with the blocks evicted). Safe to call while running; threads
  // computing at that moment may still add one event each.
  void SetTrace(std::shared_ptr<Trace> trace);

  ActopoStructure(const ActopoStructure&) = delete;
  ActopoStructure& operator=(const ActopoStructure&) = delete;

  class Consumer;

  // The block a relation's last span points into, and whether this reader pins it there.
  struct Slot : RelationSlot {
    int32_t block = -1;
    bool pinned = false;  // false: empty, or a block the reader computed itself (Reader::own_)
  };

  class Reader : public BlockSlotReader<Reader, Slot> {
   public:
    Reader(Reader&& other) noexcept;
    Reader& operator=(Reader&&) = delete;
    ~Reader();  // releases its pins and its consumer slot

    // ReaderBase::Finished: drops this reader's pins on `block` and evicts its relations from
    // the consumer's buffer (those no other pin or computation holds).
    void Finished(int32_t block);

   private:
    friend class ActopoStructure;
    friend class BlockSlotReader<Reader, Slot>;
    Reader(const Topology* topology, Consumer* consumer);
    void MoveSlot(Relation r, int32_t block);
    void Release(Relation r);

    Consumer* consumer_;
    // Relations this reader computed for itself (see MoveSlot).
    std::array<std::unique_ptr<RelationBlock>, kNumRelations> own_;
    // For what the consumer computes on its thread: it goes with the reader, so no thread of a
    // server's pool keeps the largest block's scratch after the job (it would, thread_local).
    BlockScratch scratch_;
    int32_t last_block_ = -1;
  };

  // Traits (structures.h): producers compute relations ahead into the shared buffer.
  static constexpr bool kRelationsInPlace = false;
  static constexpr bool kPrefetches = true;

  // Binds the calling thread's reader to a free consumer; at most `consumers` at once (more is a
  // programming error and aborts).
  Reader NewReader();

  const Topology& topology() const { return *topology_; }
  const Options& options() const { return options_; }
  int buffer_capacity_blocks() const { return capacity_; }

  // Per consumer and summed. Safe to call while running.
  std::vector<EngineStats> consumer_stats() const;
  EngineStats stats() const;
  MemoryStats memory() const;

 private:
  ActopoStructure(std::shared_ptr<const Topology> topology, const Options& options);

  std::shared_ptr<const Topology> topology_;
  const Options options_;
  int capacity_ = 1;
  std::vector<std::unique_ptr<Consumer>> consumers_;
};

}  // namespace actopo

#endif  // ACTOPO_SERVER_CORE_ACTOPO_STRUCTURE_H_
