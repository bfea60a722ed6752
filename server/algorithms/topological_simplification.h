// topological-simplification: TTK's TopologicalSimplification with its default backend, LTS
// (Lukasczyk, Garth, Maciejewski, Tierny, "Localized Topological Simplification of Scalar
// Data", IEEE TVCG 2021), driven by the persistence diagram as TTK users chain the filters:
// the pairs with persistence >= the threshold keep their vertices (the constraints); every other
// local maximum (then, on the inverted order, every other minimum) is removed by flattening its
// superlevel-set component, grown from the maximum until the saddle where it meets the rest, to
// the saddle's value, and re-ordering the flattened vertices so that none is an extremum.
//
//   ASSIGN_OR_RETURN(SimplificationResult s,
//                    RunTopologicalSimplification(*structure, order, scalars,
//                                                 {.threshold = 0.01, .relative = true}, {}));
//   s.scalars;  // the simplified field, by input vertex id; s.order its vertex order
//
// Parity with TTK: TTK grows the components in parallel and the last one to reach a saddle
// goes on; here they grow one after another in ascending order of their maxima, which gives the
// same components. The flattened values are copies of saddle values, so the field keeps its
// type; TTK's optional numerical perturbation is not applied (its default).
#ifndef ACTOPO_SERVER_ALGORITHMS_TOPOLOGICAL_SIMPLIFICATION_H_
#define ACTOPO_SERVER_ALGORITHMS_TOPOLOGICAL_SIMPLIFICATION_H_

#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "server/algorithms/consumers.h"
#include "server/algorithms/persistence_diagram.h"
#include "server/core/relation.h"
#include "server/core/structures.h"

namespace actopo {

struct SimplificationOptions {
  // Pairs with Persistence() >= threshold are kept (an absolute scalar difference, or a fraction
  // of the field's range when `relative`). 0 keeps every pair: nothing changes.
  double threshold = 0;
  bool relative = false;
  // TTK's legacy backend instead of LTS (Tierny, Pascucci, "Generalized Topological
  // Simplification of Scalar Fields on Surfaces", IEEE TVCG 2012): sweeps from the kept minima
  // up and from the kept maxima down, each vertex raised (lowered) to its predecessor's value
  // when below (above) it, repeated until the only extrema left are kept ones. Slower; every
  // vertex's order changes.
  bool legacy = false;
};

struct SimplificationStats {
  int64_t kept_pairs = 0, removed_pairs = 0;
  int64_t constraints = 0;  // distinct vertices of the kept pairs
  int64_t removed_maxima = 0, removed_minima = 0;
  int64_t changed_values = 0;      // vertices whose value changed
  int64_t maxima = 0, minima = 0;  // local extrema of the simplified field
  int64_t sweeps = 0;              // legacy backend: up-and-down iterations
};

struct SimplificationResult {
  PersistenceDiagramResult diagram;  // of the input field, before simplification
  double threshold = 0;              // absolute
  bool legacy = false;               // the backend that ran
  SimplificationStats stats;
  std::vector<double> scalars;   // the simplified field, by input vertex id
  std::vector<SimplexId> order;  // its vertex order (TTK's "<field>_Order"), by input id
  // The same order by internal vertex id, for running another algorithm on the result.
  std::vector<SimplexId> internal_order;
  // LTS: the vertices it flattened (internal ids, ascending). They are the only ones whose order
  // moved against the others: any two other vertices compare in `internal_order` as in the
  // input's, so the diagram's gradient needs updating only around them (UpdateDiscreteGradient).
  // Empty with the legacy backend, whose sweeps may move any vertex.
  std::vector<SimplexId> reordered;
  // The vertices whose lower star the simplification changed (internal ids, ascending):
  // `reordered`, and each of their neighbours whose lower neighbours no longer come in the same
  // order. The stars the gradient update pairs again (UpdateDiscreteGradient's `changed`), found
  // while the simplification held every vertex's neighbours.
  std::vector<SimplexId> changed_stars;

  // "<vertex id> <value %.17g>\n" and "<vertex id> <order>\n" per vertex, ascending id.
  std::string ScalarsDigest() const;
  std::string OrderDigest() const;
};

// The diagram's relations and VV (the propagations' neighbourhoods).
RelationSet TopologicalSimplificationDeclared();
// What it reads from a localized structure block by block: the diagram's relations only. There
// the neighbourhoods come from the rows the diagram's gradient pass keeps (VertexNeighbors);
// only the explicit structure serves VV itself.
RelationSet TopologicalSimplificationSwept();

// Validates the options against the field: a finite, non-negative threshold (relative: at most 1).
absl::Status ValidateSimplificationOptions(const SimplificationOptions& options);

// `order` and `scalars` as for RunPersistenceDiagram. The diagram runs on every consumer; the
// propagations, one after another, on one.
template <TopologicalStructure Structure>
absl::StatusOr<SimplificationResult> RunTopologicalSimplification(
    Structure& structure, std::span<const SimplexId> order, std::span<const double> scalars,
    const SimplificationOptions& options, const RunContext& context);

}  // namespace actopo

#endif  // ACTOPO_SERVER_ALGORITHMS_TOPOLOGICAL_SIMPLIFICATION_H_
