// Runs any algorithm on any structure, and summarises its result as the JSON object that
// actopo-bench prints and the service returns (DESIGN.md "Command-line contracts").
//
//   AlgorithmInput input{.algorithm = Algorithm::kMorseSmale, .order = ..., ...};
//   ASSIGN_OR_RETURN(AlgorithmOutcome outcome, RunAlgorithm(*structure, input, context));
//   nlohmann::ordered_json result = Summarize(outcome, *topology, {.digests = true});
#ifndef ACTOPO_SERVER_RESULTS_RUN_ALGORITHM_H_
#define ACTOPO_SERVER_RESULTS_RUN_ALGORITHM_H_

#include <map>
#include <memory>
#include <optional>
#include <string>
#include <variant>
#include <vector>

#include "absl/status/statusor.h"
#include "nlohmann/json.hpp"
#include "server/algorithms/consumers.h"
#include "server/algorithms/critical_points.h"
#include "server/algorithms/discrete_gradient.h"
#include "server/algorithms/merge_tree.h"
#include "server/algorithms/morse_smale.h"
#include "server/algorithms/persistence_diagram.h"
#include "server/algorithms/registry.h"
#include "server/algorithms/topo_relations.h"
#include "server/algorithms/topological_simplification.h"
#include "server/core/structures.h"
#include "server/diagrams/distance.h"

namespace actopo {

// diagram-distance: how the fields' diagrams are compared.
struct DistanceParameters {
  diagrams::DistanceOptions options;
  // Pairs less persistent than this are left out of both diagrams: an absolute persistence, or
  // with `relative` a fraction of each field's own range. 0 keeps every pair.
  double threshold = 0;
  bool relative = false;
  // diagram-distance: the matching behind the entry (i, j) of the matrix, when asked.
  std::optional<std::pair<int32_t, int32_t>> matching;
  // The threshold for a field with these values.
  double ThresholdFor(std::span<const double> values) const;
};

struct AlgorithmInput {
  Algorithm algorithm = Algorithm::kTopoRelations;
  std::vector<SimplexId> order;  // VertexOrder(); empty for topo-relations
  // morse-smale: InputCorners of the mesh, shared by the jobs of a session.
  std::shared_ptr<const std::vector<uint8_t>> input_corners;
  // The field by input vertex id (persistence-diagram, topological-simplification, morse-smale).
  std::vector<double> scalars;
  CriticalPointsOptions critical_points;
  TopoRelationsOptions topo_relations;
  bool embed_diagram_in_domain = false;  // persistence-diagram outputs
  TreeType tree = TreeType::kJoin;       // merge-tree: join or split
  // topological-simplification (default: 1% of the range); morse-smale and the trees simplify
  // first when set.
  std::optional<SimplificationOptions> simplification;
  DistanceParameters distance;  // diagram-distance, tracking
};

// morse-smale with a persistence threshold: the complex of the simplified field.
struct SimplifiedMorseSmaleResult {
  SimplificationResult simplification;
  MorseSmaleResult morse_smale;
};

// A tree with a persistence threshold: the tree of the simplified field.
struct SimplifiedTreeResult {
  SimplificationResult simplification;
  TreeResult tree;
};

// Algorithm parameters by name, as the service receives them: "boundary_rule" = "ttk" | "none"
// (critical-points); "relations" = "ttk" (TTK's 20, the default) | "all" (22: with EE and FF;
// topo-relations); "embedding" = "diagram" | "domain" (persistence-diagram: pairs at
// (birth, death) or at their vertices); "persistence_threshold" = an absolute persistence, or
// "relative_threshold" = a fraction of the field's range (topological-simplification, and
// morse-smale, merge-tree and contour-tree, which then run on the simplified field); "tree" =
// "join" (default) | "split" (merge-tree), "backend" = "lts" (default) |
// "legacy"; diagram-distance and tracking: "p" = the Wasserstein order (default 2),
// "persistence_threshold" or "relative_threshold" (pairs below it left out, default none),
// "essential" = "true" | "false" (match the infinite pairs too), and for diagram-distance
// "matching" = "I,J" (the matching behind that entry: fields I and J of the list, from 0).
// Unknown names and values are errors naming them.
absl::Status ApplyParameters(const std::map<std::string, std::string>& parameters,
                             AlgorithmInput& input);

using AlgorithmResult =
    std::variant<TopoRelationsResult, CriticalPointsResult, DiscreteGradientResult,
                 MorseSmaleResult, PersistenceDiagramResult, SimplificationResult,
                 SimplifiedMorseSmaleResult, TreeResult, SimplifiedTreeResult>;

struct AlgorithmOutcome {
  AlgorithmResult result;
  double run_s = 0;
  int64_t peak_rss_after_run = 0;  // before summaries, which can be large
};

// Whether a run of `input` reads edges or triangles: its algorithm's, or a simplification first.
bool NeedsFaces(const AlgorithmInput& input);
// Whether it reads the field's values (AlgorithmInput::scalars), not only their order.
bool NeedsScalarValues(const AlgorithmInput& input);

// The relations a run of `input` reads: its algorithm's declared set, and the simplification's
// when morse-smale or a tree simplifies first.
RelationSet DeclaredRelations(const AlgorithmInput& input);
// Of those, what it reads on every block (SweptRelations): actopo's producers compute these
// ahead (ActopoStructure::Options::declared).
RelationSet SweptRelations(const AlgorithmInput& input);

// Defined for the explicit, compact and actopo structures.
template <TopologicalStructure Structure>
absl::StatusOr<AlgorithmOutcome> RunAlgorithm(Structure& structure, const AlgorithmInput& input,
                                              const RunContext& context);

struct SummaryOptions {
  // Add the result's SHA-256 digests (the `*_sha256` keys, DESIGN.md "Digests"): what fidelity
  // checks compare with TTK. Off by default: on a 10M-tet mesh the gradient's pair digest alone
  // hashes about 35M lines, a third of the job.
  bool digests = false;
};

// actopo-bench's "result" object, and the job summary the service sends.
nlohmann::ordered_json Summarize(const AlgorithmResult& result, const Topology& topology,
                                 const SummaryOptions& options = {});

}  // namespace actopo

#endif  // ACTOPO_SERVER_RESULTS_RUN_ALGORITHM_H_
