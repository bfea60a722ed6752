#include "server/algorithms/registry.h"

#include <array>
#include <string>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "server/algorithms/critical_points.h"
#include "server/algorithms/discrete_gradient.h"
#include "server/algorithms/merge_tree.h"
#include "server/algorithms/morse_smale.h"
#include "server/algorithms/persistence_diagram.h"
#include "server/algorithms/topo_relations.h"
#include "server/algorithms/topological_simplification.h"

namespace actopo {
namespace {

constexpr std::array<Algorithm, 10> kAll = {
    Algorithm::kTopoRelations,      Algorithm::kCriticalPoints,
    Algorithm::kDiscreteGradient,   Algorithm::kMorseSmale,
    Algorithm::kPersistenceDiagram, Algorithm::kTopologicalSimplification,
    Algorithm::kDiagramDistance,    Algorithm::kTracking,
    Algorithm::kMergeTree,          Algorithm::kContourTree};

}  // namespace

std::string_view AlgorithmName(Algorithm a) {
  switch (a) {
    case Algorithm::kTopoRelations: return "topo-relations";
    case Algorithm::kCriticalPoints: return "critical-points";
    case Algorithm::kDiscreteGradient: return "discrete-gradient";
    case Algorithm::kMorseSmale: return "morse-smale";
    case Algorithm::kPersistenceDiagram: return "persistence-diagram";
    case Algorithm::kTopologicalSimplification: return "topological-simplification";
    case Algorithm::kDiagramDistance: return "diagram-distance";
    case Algorithm::kTracking: return "tracking";
    case Algorithm::kMergeTree: return "merge-tree";
    case Algorithm::kContourTree: return "contour-tree";
  }
  return "?";
}

absl::StatusOr<Algorithm> ParseAlgorithm(std::string_view name) {
  std::string dashed(name);
  for (char& c : dashed) {
    if (c == '_') c = '-';
  }
  std::vector<std::string> names;
  for (Algorithm a : kAll) {
    if (AlgorithmName(a) == dashed) return a;
    names.emplace_back(AlgorithmName(a));
  }
  return absl::InvalidArgumentError(absl::StrCat("algorithm: unknown algorithm '",
                                                 std::string(name),
                                                 "'; available: ", absl::StrJoin(names, ", ")));
}

std::span<const Algorithm> AllAlgorithms() { return kAll; }

bool ComparesFields(Algorithm a) {
  return a == Algorithm::kDiagramDistance || a == Algorithm::kTracking;
}

RelationSet DeclaredRelations(Algorithm a) {
  switch (a) {
    case Algorithm::kTopoRelations: return TopoRelationsDeclared();
    case Algorithm::kCriticalPoints: return CriticalPointsDeclared();
    case Algorithm::kDiscreteGradient: return DiscreteGradientDeclared();
    case Algorithm::kMorseSmale: return MorseSmaleDeclared();
    case Algorithm::kPersistenceDiagram:
    case Algorithm::kDiagramDistance:
    case Algorithm::kTracking: return PersistenceDiagramDeclared();
    case Algorithm::kTopologicalSimplification: return TopologicalSimplificationDeclared();
    case Algorithm::kMergeTree:
    case Algorithm::kContourTree: return TreeDeclared();
  }
  return {};
}

RelationSet SweptRelations(Algorithm a) {
  switch (a) {
    case Algorithm::kCriticalPoints: return CriticalPointsSwept();
    case Algorithm::kTopologicalSimplification: return TopologicalSimplificationSwept();
    case Algorithm::kMergeTree:
    case Algorithm::kContourTree: return TreeSwept();
    default: return DeclaredRelations(a);
  }
}

bool NeedsFaces(Algorithm a) {
  // Critical points reads VT and VB and no other part of the topology's faces, the trees VT and
  // VV.
  static_assert(!NeedsFaces(Relation::kVT) && !NeedsFaces(Relation::kVB) &&
                !NeedsFaces(Relation::kVV));
  return a != Algorithm::kCriticalPoints && a != Algorithm::kMergeTree &&
         a != Algorithm::kContourTree;
}

bool NeedsScalar(Algorithm a) { return a != Algorithm::kTopoRelations; }

bool NeedsScalarValues(Algorithm a) {
  return a == Algorithm::kPersistenceDiagram || a == Algorithm::kTopologicalSimplification ||
         a == Algorithm::kMorseSmale || ComparesFields(a);
}

Prefetch DefaultPrefetch(Algorithm) {
  // Every algorithm reads relations block by block on every consumer (Morse-Smale's
  // separatrices touch few blocks): linear beats spatial on Morse-Smale too.
  return Prefetch::kLinear;
}

Precompute DefaultPrecompute(Algorithm a) {
  // The persistence diagram and the simplification read the gradient's lower stars, then a few
  // stars along paths: like the gradient.
  return a == Algorithm::kTopoRelations || a == Algorithm::kMorseSmale ? Precompute::kRequested
                                                                       : Precompute::kDeclared;
}

}  // namespace actopo
