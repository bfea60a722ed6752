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
// for the hand-off) or by the consumer (kConsumer, the default: on 2 cores it ran topo-relations
// 1.6x and Morse-Smale 1.4x faster, see bench/RESULTS.md); either way never twice at once.
// While no request is pending the leader prefetches too (one task at a time, so a new request
// waits at most one block computation): when the consumer reads faster than one producer
// computes, which is the common case, an idle leader would waste a core.
//
// What this implementation guarantees beyond the reference code:
// - each (block, relation) has a state (absent, computing, ready): nothing is computed twice at
//   once, and an empty relation is still "ready";
// - producers sleep on a condition variable when there is nothing useful to do;
// - eviction (oldest half of the buffer by insertion) never frees a relation a consumer is
//   reading: the consumer pins it (an atomic count) and eviction skips pinned entries;
// - the configuration is fixed before any thread starts; destruction stops and joins every
//   thread, also while a consumer waits on a miss (that consumer then computes the relation
//   itself, so its results stay correct).
//
// A read inside the block a reader is already on is a comparison; moving to another block is a
// few atomic operations on a hit, and takes the consumer's mutex only on a miss and, once per
// prefetch window, to tell the leader where the consumer has got to.
#ifndef ACTOPO_SERVER_CORE_ACTOPO_STRUCTURE_H_
#define ACTOPO_SERVER_CORE_ACTOPO_STRUCTURE_H_

#include <array>
#include <atomic>
#include <cstdint>
#include <memory>
#include <string_view>
#include <vector>

#include "absl/status/statusor.h"
#include "server/core/block_relations.h"
#include "server/core/relation.h"
#include "server/core/stats.h"
#include "server/core/structure.h"
#include "server/core/topology.h"
#include "server/core/trace.h"

namespace actopo {

// Which blocks producers compute ahead of the consumer.
enum class Prefetch : uint8_t {
  kLinear,    // b + 1, b + 2, ...
  kSpatial,   // blocks sharing a tetrahedron with b, ascending
  kAdaptive,  // the blocks this consumer has most often moved to from b (learned online), then
              // spatial neighbours for the rest of the window
};
// Who computes a relation the consumer misses when no producer is already computing it.
enum class MissPolicy : uint8_t {
  kLeader,    // the paper's protocol: the consumer asks its leader and waits
  kConsumer,  // the consumer computes it itself (no thread hand-off) and only tells the leader
              // where it is, so the workers re-target
};

// Which relations producers compute for a prefetched block.
enum class Precompute : uint8_t {
  kRequested,  // the relation the consumer last asked for
  kDeclared,   // every relation of the algorithm's declared set
};

std::string_view PrefetchName(Prefetch p);
std::string_view MissPolicyName(MissPolicy p);
std::string_view PrecomputeName(Precompute p);

// Engine counters of one consumer (and summed per session).
struct EngineStats {
  AccessStats access;
  int64_t leader_relations = 0;     // (block, relation) computed by leaders
  int64_t worker_relations = 0;     // ... by workers
  int64_t consumer_relations = 0;   // ... by consumers themselves (only while shutting down)
  int64_t duplicates_avoided = 0;   // tasks skipped because already computing or ready
  int64_t blocks_inserted = 0;      // blocks that entered the buffer
  int64_t producer_busy_ns = 0;     // time producers spent computing
  int64_t buffer_bytes = 0;         // now
  int64_t buffer_peak_bytes = 0;
  int64_t buffer_blocks = 0;        // resident blocks now
  int64_t buffer_peak_blocks = 0;   // at most capacity + 1 + blocks pinned by the consumer

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
    RelationSet declared = RelationSet::All();  // used by Precompute::kDeclared
    MissPolicy miss_policy = MissPolicy::kConsumer;  // measured faster; kLeader: the paper
  };

  // Validates the options (each error names the option and value) and starts C * P threads.
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

  // Records into `trace` from now on (null: stop): per thread, spans for every (block,
  // relation) computed (named by the relation's code, category leader, worker or consumer),
  // every consumer wait on a miss ("wait", category consumer), and an instant per eviction
  // ("evict", category buffer, with the blocks evicted). Safe to call while running; threads
  // computing at that moment may still add one event each.
  void SetTrace(std::shared_ptr<Trace> trace);

  ActopoStructure(const ActopoStructure&) = delete;
  ActopoStructure& operator=(const ActopoStructure&) = delete;

  class Consumer;

  class Reader : public ReaderBase<Reader> {
   public:
    Reader(Reader&& other) noexcept;
    Reader& operator=(Reader&&) = delete;
    ~Reader();  // releases its pins and its consumer slot

    template <Relation R>
    std::span<const SimplexId> Lookup(SimplexId s) {
      Slot& slot = slots_[Index(R)];
      if (!slot.Contains(s)) [[unlikely]] {
        MoveSlot(R, topology_->block_of(SourceDimension(R), s));
      }
      return slot.template Row<R>(s);
    }

   private:
    friend class ActopoStructure;
    struct Slot : RelationSlot {
      int32_t block = -1;
      void* cell = nullptr;  // the pinned buffer cell, or null for a consumer-computed block
    };
    Reader(const Topology* topology, Consumer* consumer);
    void MoveSlot(Relation r, int32_t block);
    void Release(Slot& slot);

    Consumer* consumer_;
    std::array<Slot, kNumRelations> slots_;
    // Relations this consumer computed itself while the engine was stopping.
    std::array<std::unique_ptr<RelationBlock>, kNumRelations> own_;
    int32_t last_block_ = -1;
  };

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
