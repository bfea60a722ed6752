// Phase controls of a structure that prefetches (kPrefetches: actopo), no-ops on the others.
// PrefetchOff switches its prefetching off for a scope: for phases whose reads follow V-paths and
// walls across blocks, not blocks in order, where speculative block computations only compete with
// the consumers. DropBufferedRelations empties its buffers between phases (compact's caches belong
// to readers, which end with their phase; explicit's relations are the structure); EndPhase also
// returns the memory freed to the system.
//
//   {
//     PrefetchOff<Structure> off(structure);
//     ... trace paths ...
//   }
//   DropBufferedRelations(structure);  // the next phase reads other relations
#ifndef ACTOPO_SERVER_ALGORITHMS_PREFETCH_OFF_H_
#define ACTOPO_SERVER_ALGORITHMS_PREFETCH_OFF_H_

#include "server/core/process_memory.h"
#include "server/core/structures.h"

namespace actopo {

template <TopologicalStructure Structure>
class PrefetchOff {
 public:
  explicit PrefetchOff(Structure& structure) : structure_(structure) {
    if constexpr (Structure::kPrefetches) structure_.SetPrefetching(false);
  }
  ~PrefetchOff() {
    if constexpr (Structure::kPrefetches) structure_.SetPrefetching(true);
  }
  PrefetchOff(const PrefetchOff&) = delete;
  PrefetchOff& operator=(const PrefetchOff&) = delete;

 private:
  Structure& structure_;
};

template <TopologicalStructure Structure>
void DropBufferedRelations(Structure& structure) {
  if constexpr (Structure::kPrefetches) structure.DropBufferedRelations();
}

// Between two phases of an algorithm on any structure: drops actopo's buffered relations and,
// on meshes of 1M tetrahedra or more, hands the allocator's free memory back to the system.
// What the last phase's threads freed (its arrays, compact's caches, the kept neighbours) stays
// in their arenas otherwise, beside the next phase's arrays, which other threads allocate.
// malloc_trim walks every arena and stalls other sessions' allocations meanwhile: not worth it
// on the small meshes a server may run many jobs a second on.
template <TopologicalStructure Structure>
void EndPhase(Structure& structure) {
  DropBufferedRelations(structure);
  constexpr SimplexId kWorthReturning = 1 << 20;  // tetrahedra
  if (structure.topology().num_tetrahedra() >= kWorthReturning) ReleaseFreeMemory();
}

}  // namespace actopo

#endif  // ACTOPO_SERVER_ALGORITHMS_PREFETCH_OFF_H_
