// The algorithms the service and actopo-bench run, by name, with what the engine needs to know
// about each: its declared relations and its best prefetch mode (the `auto` choices).
//
//   ASSIGN_OR_RETURN(Algorithm a, ParseAlgorithm("critical-points"));
//   RelationSet needs = DeclaredRelations(a);
#ifndef ACTOPO_SERVER_ALGORITHMS_REGISTRY_H_
#define ACTOPO_SERVER_ALGORITHMS_REGISTRY_H_

#include <span>
#include <string_view>

#include "absl/status/statusor.h"
#include "server/core/actopo_structure.h"
#include "server/core/relation.h"

namespace actopo {

enum class Algorithm : uint8_t {
  kTopoRelations,
  kCriticalPoints,
  kDiscreteGradient,
  kMorseSmale,
  kPersistenceDiagram,
  kTopologicalSimplification,
  // A field list's persistence diagrams, then the distances between every two of them
  // (server/diagrams): per field it runs as the persistence diagram.
  kDiagramDistance,
  // A series' persistence diagrams, consecutive ones matched and the matches chained into
  // trajectories (server/diagrams/tracking.h): per field it runs as the persistence diagram.
  kTracking,
  // TTK's MergeTree: the join tree (parameter tree = join, the default) or the split tree.
  kMergeTree,
  // TTK's ContourTree: the join and split trees combined.
  kContourTree,
};

std::string_view AlgorithmName(Algorithm a);  // "critical-points"
// Accepts "critical-points" and "critical_points"; the error lists the algorithms.
absl::StatusOr<Algorithm> ParseAlgorithm(std::string_view name);
std::span<const Algorithm> AllAlgorithms();
// Whether the algorithm compares fields (a list of at least two) instead of analysing one.
bool ComparesFields(Algorithm a);

RelationSet DeclaredRelations(Algorithm a);
// The declared relations the algorithm reads block by block on actopo, which its producers
// compute ahead under Precompute::kDeclared: all of them but critical points' VB (read only
// around boundary vertices), the simplification's VV (read from rows the diagram keeps) and the
// trees' VV (read only where stored). Prefetching those would compute blocks nobody asks for.
RelationSet SweptRelations(Algorithm a);
// Whether the algorithm reads edges or triangles (its relations or the topology's), so needs a
// topology built with faces (TopologyOptions::faces): every one but critical points and the
// trees (which simplify first only with a threshold: run_algorithm.h's NeedsFaces(input)).
bool NeedsFaces(Algorithm a);
// Whether the algorithm reads a scalar field.
bool NeedsScalar(Algorithm a);
// Whether it needs the field's values, not only their order: the persistence diagram reports
// them and the simplification (alone or before Morse-Smale) rewrites them.
bool NeedsScalarValues(Algorithm a);

// Engine modes per algorithm: linear prefetch for all (each consumer sweeps its blocks in
// order); critical points and discrete gradient precompute every declared relation, the others
// the requested one.
Prefetch DefaultPrefetch(Algorithm a);
Precompute DefaultPrecompute(Algorithm a);

}  // namespace actopo

#endif  // ACTOPO_SERVER_ALGORITHMS_REGISTRY_H_
