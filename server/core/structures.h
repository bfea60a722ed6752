// The structures an algorithm runs on, and the contract they share: what an algorithm may ask
// of a structure, checked at compile time (TopologicalStructure), and the one list of them from
// which every algorithm's instantiations follow (ACTOPO_FOR_EACH_STRUCTURE).
//
//   template <TopologicalStructure S>
//   absl::StatusOr<int64_t> CountStars(S& structure, const RunContext& context);
//
//   #define ACTOPO_INSTANTIATE(S) template absl::StatusOr<int64_t> CountStars(S&, ...);
//   ACTOPO_FOR_EACH_STRUCTURE(ACTOPO_INSTANTIATE)
//   #undef ACTOPO_INSTANTIATE
//
// A structure gives the topology, a Reader per consumer thread (structure.h: the relation
// accessors, and Finished(block) once a consumer is done with a block's relations), and says
// what it is through two traits instead of algorithms testing its type:
//   kRelationsInPlace  every relation is precomputed for the whole run, so a row can be read (and
//                      kept) in place, and nothing needs copying aside (explicit);
//   kPrefetches        producers compute relations ahead of the consumers into a buffer: then
//                      SetPrefetching(bool) pauses them for phases whose reads follow no block
//                      order, and DropBufferedRelations() empties the buffer between phases
//                      (actopo).
// SetTrace(trace) records a structure's own events; a structure that has none need not have it.
// Adding a structure: a class meeting the concept, and its name in ACTOPO_FOR_EACH_STRUCTURE.
#ifndef ACTOPO_SERVER_CORE_STRUCTURES_H_
#define ACTOPO_SERVER_CORE_STRUCTURES_H_

#include <concepts>
#include <cstdint>
#include <memory>

#include "server/core/actopo_structure.h"
#include "server/core/compact_structure.h"
#include "server/core/explicit_structure.h"
#include "server/core/topology.h"
#include "server/core/trace.h"

namespace actopo {

// What a structure that prefetches (kPrefetches) also offers.
template <class S>
concept PrefetchControls = requires(S& s) {
  s.SetPrefetching(true);
  s.DropBufferedRelations();
};

template <class S>
concept TopologicalStructure = requires(S& s, const S& cs, int32_t block) {
  { cs.topology() } -> std::same_as<const Topology&>;
  s.NewReader().Finished(block);
  { S::kRelationsInPlace } -> std::convertible_to<bool>;
  { S::kPrefetches } -> std::convertible_to<bool>;
  requires !S::kPrefetches || PrefetchControls<S>;
};

// Whether the structure records events of its own (SetTrace).
template <class S>
constexpr bool kTraces = requires(S& s, std::shared_ptr<Trace> trace) {
  s.SetTrace(trace);
};

#define ACTOPO_FOR_EACH_STRUCTURE(X) X(ExplicitStructure) X(CompactStructure) X(ActopoStructure)

static_assert(TopologicalStructure<ExplicitStructure>);
static_assert(TopologicalStructure<CompactStructure>);
static_assert(TopologicalStructure<ActopoStructure>);

}  // namespace actopo

#endif  // ACTOPO_SERVER_CORE_STRUCTURES_H_
