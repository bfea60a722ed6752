// Phase controls of an actopo structure, no-ops on the others. PrefetchOff switches its
// prefetching off for a scope: for phases whose reads follow V-paths and walls across blocks, not
// blocks in order, where speculative block computations only compete with the consumers.
// DropBufferedRelations empties its buffers between phases (compact's caches belong to readers,
// which end with their phase; explicit's relations are the structure).
//
//   {
//     PrefetchOff<Structure> off(structure);
//     ... trace paths ...
//   }
//   DropBufferedRelations(structure);  // the next phase reads other relations
#ifndef ACTOPO_SERVER_ALGORITHMS_PREFETCH_OFF_H_
#define ACTOPO_SERVER_ALGORITHMS_PREFETCH_OFF_H_

#include <type_traits>

#include "server/core/actopo_structure.h"

namespace actopo {

template <class Structure>
class PrefetchOff {
 public:
  explicit PrefetchOff(Structure& structure) : structure_(structure) {
    if constexpr (kActopo) structure_.SetPrefetching(false);
  }
  ~PrefetchOff() {
    if constexpr (kActopo) structure_.SetPrefetching(true);
  }
  PrefetchOff(const PrefetchOff&) = delete;
  PrefetchOff& operator=(const PrefetchOff&) = delete;

 private:
  static constexpr bool kActopo = std::is_same_v<Structure, ActopoStructure>;
  Structure& structure_;
};

template <class Structure>
void DropBufferedRelations(Structure& structure) {
  if constexpr (std::is_same_v<Structure, ActopoStructure>) structure.DropBufferedRelations();
}

}  // namespace actopo

#endif  // ACTOPO_SERVER_ALGORITHMS_PREFETCH_OFF_H_
