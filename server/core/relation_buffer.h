// One ACTOPO consumer's bounded buffer of block relations: a state per (block, relation), pins
// that keep a relation alive while the consumer reads it, and eviction of the oldest half of the
// resident blocks when a block beyond capacity comes in.
//
//   RelationBuffer buffer(topology.num_blocks(), /*capacity_blocks=*/4);
//   if (buffer.StartComputing(b, r)) {                       // absent -> computing: ours
//     buffer.Publish(b, r, std::make_unique<RelationBlock>(...), /*pin=*/false);
//   }
//   if (const RelationBlock* data = buffer.TryPin(b, r)) {   // lock-free on the hot path
//     ... read data ...
//     buffer.Unpin(b, r);
//   }
//
// State of each (block, relation), and who moves it:
//
//   absent --StartComputing--> computing --Publish--> ready --eviction--> absent
//                                                       ^        |
//                                                       +--------+ pinned: stays ready
//
// Eviction passes through a transient "evicting" state (ready -> evicting, then absent, or back
// to ready when a pin is seen). TryPin increments the pin count before reading the state and
// eviction marks the state before reading the pin count, both sequentially consistent: of a
// consumer pinning and a producer evicting the same relation, at least one sees the other, so
// data is never freed under a reader. An empty relation is "ready" like any other.
//
// Thread safety: TryPin, Unpin, state and stats are lock-free from any thread; StartComputing is
// an atomic compare-and-swap; Publish takes the buffer's mutex (it guards the resident list), the
// innermost lock of the engine.
#ifndef ACTOPO_SERVER_CORE_RELATION_BUFFER_H_
#define ACTOPO_SERVER_CORE_RELATION_BUFFER_H_

#include <atomic>
#include <cstdint>
#include <memory>
#include <vector>

#include "absl/base/thread_annotations.h"
#include "server/core/block_relations.h"
#include "server/core/relation.h"
#include "server/core/sync.h"

namespace actopo {

class RelationBuffer {
 public:
  enum class State : uint8_t { kAbsent, kComputing, kReady, kEvicting };

  struct Stats {
    int64_t bytes = 0;  // relation data resident now
    int64_t peak_bytes = 0;
    int64_t blocks = 0;           // blocks with a relation resident now
    int64_t peak_blocks = 0;      // at most capacity + 1 + blocks kept by pins or computations
    int64_t blocks_inserted = 0;  // times a block entered the buffer
    int64_t evictions = 0;        // times a block left it
  };

  // capacity_blocks >= 1.
  RelationBuffer(int32_t num_blocks, int capacity_blocks);
  ~RelationBuffer();  // frees every resident relation; no pin may be held
  RelationBuffer(const RelationBuffer&) = delete;
  RelationBuffer& operator=(const RelationBuffer&) = delete;

  // The data of (block, r), pinned, if it is ready; null otherwise. Valid until Unpin(block, r).
  const RelationBlock* TryPin(int32_t block, Relation r);
  void Unpin(int32_t block, Relation r);

  // A snapshot; by the time the caller looks, another thread may have moved it on.
  State state(int32_t block, Relation r) const;

  // absent -> computing. False when it was not absent: someone computes it, or it is there.
  bool StartComputing(int32_t block, Relation r);

  // computing -> ready with `data`, pinned once for the caller if `pin` (taken before any
  // eviction can look at it). When this brings a new block in beyond capacity, the oldest half
  // of the resident blocks (by insertion) is evicted, sparing `block`, blocks with a relation
  // being computed and pinned relations (a block with a pinned relation stays resident).
  // Returns the evicted relations' data, for the caller to free once it holds no lock of its
  // own: half a buffer can be tens of megabytes, and nobody should wait on a lock while it is
  // returned to the system.
  struct Evicted {
    int blocks = 0;
    std::vector<std::unique_ptr<RelationBlock>> data;
  };
  Evicted Publish(int32_t block, Relation r, std::unique_ptr<RelationBlock> data, bool pin);

  // Evicts every resident block whose relations no one pins or computes (between an
  // algorithm's phases, when what the last phase kept is not what the next reads).
  Evicted EvictAll();
  // Evicts `block`'s relations that no one pins or computes, at once (its reader is done with
  // it); the block stays resident while any of them is left.
  Evicted Evict(int32_t block);

  Stats stats() const;
  int capacity_blocks() const { return capacity_; }

 private:
  struct Cell {
    std::atomic<State> state{State::kAbsent};
    std::atomic<int32_t> pins{0};
    std::atomic<RelationBlock*> data{nullptr};
  };
  Cell& cell(int32_t block, Relation r) { return cells_[size_t(block) * kNumRelations + Index(r)]; }
  const Cell& cell(int32_t block, Relation r) const {
    return cells_[size_t(block) * kNumRelations + Index(r)];
  }
  // Up to `to_evict` resident blocks, oldest first, sparing `keep` (-1: none).
  void EvictOldest(size_t to_evict, int32_t keep, Evicted& out) ABSL_EXCLUSIVE_LOCKS_REQUIRED(mu_);
  bool TryEvictBlock(int32_t block, Evicted& out) ABSL_EXCLUSIVE_LOCKS_REQUIRED(mu_);
  void AddBytes(int64_t delta);
  static void Raise(std::atomic<int64_t>& peak, int64_t value);

  const int capacity_;
  std::vector<Cell> cells_;

  Mutex mu_;
  std::vector<int32_t> resident_ ABSL_GUARDED_BY(mu_);     // oldest first
  std::vector<uint8_t> is_resident_ ABSL_GUARDED_BY(mu_);  // per block

  // Written under mu_ (bytes also by eviction's frees, under mu_ too), read by stats().
  std::atomic<int64_t> bytes_{0}, peak_bytes_{0}, blocks_{0}, peak_blocks_{0};
  std::atomic<int64_t> blocks_inserted_{0}, evictions_{0};
};

}  // namespace actopo

#endif  // ACTOPO_SERVER_CORE_RELATION_BUFFER_H_
