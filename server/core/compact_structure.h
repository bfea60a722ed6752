// The dynamic baseline: relations computed on demand by the consumer itself, one block at a time,
// and kept in a bounded cache (TopoCluster / TTK's CompactTriangulation).
//
//   CompactStructure structure(topology, {.cache_ratio = 0.2, .consumers = 2});
//   CompactStructure::Reader reader = structure.NewReader();   // one per consumer thread
//   for (SimplexId t : reader.vertex_star(v)) ...
//
// Each reader owns its cache of floor(cache_ratio * blocks / consumers) + 1 blocks, so nothing is
// shared between consumer threads and a read needs no lock. A block holds whichever relations
// were asked of it. When the cache is full, the block inserted first that no current span points
// into is evicted (blocks pinned by current spans may briefly exceed the capacity).
#ifndef ACTOPO_SERVER_CORE_COMPACT_STRUCTURE_H_
#define ACTOPO_SERVER_CORE_COMPACT_STRUCTURE_H_

#include <array>
#include <atomic>
#include <memory>
#include <vector>

#include "server/core/block_relations.h"
#include "server/core/relation.h"
#include "server/core/stats.h"
#include "server/core/structure.h"
#include "server/core/sync.h"
#include "server/core/topology.h"
#include "server/core/trace.h"

namespace actopo {

class CompactStructure {
 public:
  struct Options {
    double cache_ratio = 0.2;  // cache capacity as a fraction of the blocks, over all consumers
    int consumers = 1;         // readers that will run at once; each gets its share
  };

  CompactStructure(std::shared_ptr<const Topology> topology, const Options& options);

  // The block a relation's last span points into, and the cache entry pinned for it.
  struct Slot : RelationSlot {
    int entry = -1;
  };

  class Reader : public BlockSlotReader<Reader, Slot> {
   public:
    Reader(Reader&& other) noexcept;
    Reader& operator=(Reader&&) = delete;
    ~Reader();

    // This reader's counters so far (also added to the structure's totals on destruction).
    const AccessStats& stats() const { return stats_; }

    // ReaderBase::Finished: frees `block`'s cache entry now (its slots on it let go).
    void Finished(int32_t block);

   private:
    friend class CompactStructure;
    friend class BlockSlotReader<Reader, Slot>;
    struct Entry {
      int32_t block = -1;
      uint64_t inserted = 0;
      int pins = 0;
      std::array<std::unique_ptr<RelationBlock>, kNumRelations> relations;
    };
    explicit Reader(CompactStructure* owner);
    void MoveSlot(Relation r, int32_t block);
    int FindOrInsert(int32_t block);
    void AddBytes(int64_t delta);

    CompactStructure* owner_;
    int capacity_;
    std::vector<Entry> entries_;
    std::vector<int32_t> entry_of_block_;  // -1 when not cached
    uint64_t next_insert_ = 0;
    int64_t bytes_ = 0;
    BlockScratch scratch_;
    AccessStats stats_;
    std::shared_ptr<Trace> trace_;  // the structure's when the reader was made
  };

  // Traits (structures.h): relations computed on demand into each reader's cache; no producers.
  static constexpr bool kRelationsInPlace = false;
  static constexpr bool kPrefetches = false;

  Reader NewReader() { return Reader(this); }
  const Topology& topology() const { return *topology_; }
  // Capacity of each reader's cache, in blocks.
  int reader_capacity() const { return capacity_; }
  // Readers made from now on record into `trace` (null: stop): a span per (block, relation)
  // they compute (the relation's code, category consumer) and an instant per eviction.
  void SetTrace(std::shared_ptr<Trace> trace);
  // Totals of finished readers.
  AccessStats stats() const;
  MemoryStats memory() const;

 private:
  std::shared_ptr<const Topology> topology_;
  int capacity_;
  mutable Mutex mu_;
  AccessStats finished_ ABSL_GUARDED_BY(mu_);
  std::shared_ptr<Trace> trace_ ABSL_GUARDED_BY(mu_);
  std::atomic<int64_t> bytes_{0};  // over all live readers
  std::atomic<int64_t> peak_bytes_{0};
};

}  // namespace actopo

#endif  // ACTOPO_SERVER_CORE_COMPACT_STRUCTURE_H_
