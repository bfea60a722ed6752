// topo-relations: the relation-sweep profiling workload (SEMANTICS.md).
//
// Sweeps over all simplices of one dimension in increasing id, reading every element of one
// relation: VT, EV, ET, FV, FT, TV, VE, VF, EF, FE, TE, TF, then VV, TT, the links and the
// boundary predicates: TTK's 20 relations, by default; with `all`, also the edge and triangle
// neighbours (EE, FF), which TTK does not offer. Reports the total size of each relation and a
// checksum of what was read, so the work cannot be optimised away and results can be compared
// across structures.
//
//   ExplicitStructure::Build(topology, {.relations = TopoRelationsDeclared()});
//   ASSIGN_OR_RETURN(TopoRelationsResult r, RunTopoRelations(*structure, {.consumers = 2}));
//   RunTopoRelations(*structure, context, {.all = true});  // 22 relations
#ifndef ACTOPO_SERVER_ALGORITHMS_TOPO_RELATIONS_H_
#define ACTOPO_SERVER_ALGORITHMS_TOPO_RELATIONS_H_

#include <array>
#include <cstdint>
#include <span>
#include <string>

#include "absl/status/statusor.h"
#include "server/algorithms/consumers.h"
#include "server/core/relation.h"
#include "server/core/structures.h"

namespace actopo {

struct TopoRelationsOptions {
  bool all = false;  // also sweep EE and FF (22 relations instead of TTK's 20)
};

struct TopoRelationsResult {
  bool all = false;  // as run: which relations were swept
  // Sum over all simplices of the relation's size, indexed by Index(Relation); 0 for the
  // relations not swept.
  std::array<int64_t, kNumRelations> totals{};
  // Order-independent across consumers (a sum of per-simplex hashes), but it hashes internal
  // ids, so it depends on the partition (block size) as well as on the mesh.
  uint64_t checksum = 0;

  std::string checksum_hex() const;
};

// The sweep order: TTK's 20 relations, then EE and FF with `all`.
std::span<const Relation> TopoRelationsSweeps(bool all = false);
// What a structure needs stored for the sweeps: all relations but the edge and triangle
// neighbours, which an explicit structure composes from the others.
RelationSet TopoRelationsDeclared();

// Runs on any structure with NewReader(); defined for the explicit, compact and actopo
// structures. The actopo engine's `auto` mode uses linear prefetch of the requested relation.
template <TopologicalStructure Structure>
absl::StatusOr<TopoRelationsResult> RunTopoRelations(Structure& structure,
                                                     const RunContext& context,
                                                     TopoRelationsOptions options = {});

}  // namespace actopo

#endif  // ACTOPO_SERVER_ALGORITHMS_TOPO_RELATIONS_H_
