// persistence-diagram: TTK's PersistenceDiagram with its default backend, Discrete Morse Sandwich
// (Guillou, Vidal, Tierny, "Discrete Morse Sandwich: Fast Computation of Persistence Diagrams
// for Scalar Data", IEEE TVCG 2023), in 3D. It pairs exactly the critical cells of our discrete
// gradient (SEMANTICS.md "persistence-diagram"):
//   - min-saddle pairs (type 0): each 1-saddle's two descending V-paths reach two minima; 1-saddles
//     in filtration order merge the minima's components, the younger minimum dies (union-find);
//   - saddle-max pairs (type 2): dually, each 2-saddle's ascending V-paths reach maxima or the
//     boundary (one virtual, eternal maximum); 2-saddles in reverse order, the younger maximum
//     dies;
//   - saddle-saddle pairs (type 1): the 2-saddles left, in filtration order, reduce their boundary
//     (a mod-2 set of edges, youngest first) through the gradient's edge-triangle pairs and the
//     boundaries of earlier 2-saddles until the youngest edge is an unpaired 1-saddle, their pair;
//   - what is left never dies: infinite pairs, one per Betti number of the mesh.
// Cells compare as TTK compares them: by their vertices' orders, highest first, lexicographically.
//
//   ASSIGN_OR_RETURN(PersistenceDiagramResult d,
//                    RunPersistenceDiagram(*structure, order, scalars, {.consumers = 2}));
//   for (const PersistencePair& p : d.pairs) ... p.birth, p.death, p.Persistence() ...
//   std::string digest = d.PairsDigest();  // equals expected-ttk.json's pairs_sha256
#ifndef ACTOPO_SERVER_ALGORITHMS_PERSISTENCE_DIAGRAM_H_
#define ACTOPO_SERVER_ALGORITHMS_PERSISTENCE_DIAGRAM_H_

#include <array>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "server/algorithms/consumers.h"
#include "server/algorithms/discrete_gradient.h"
#include "server/core/relation.h"
#include "server/core/structures.h"

namespace actopo {

struct PersistencePair {
  int8_t type = 0;            // 0 min-saddle, 1 saddle-saddle, 2 saddle-max
  SimplexId birth_cell = -1;  // the critical `type`-cell (internal id)
  SimplexId death_cell = -1;  // the critical (type + 1)-cell (internal id), -1: never dies
  // The cells' highest vertices in the vertex order, as input ids (TTK's ttkVertexScalarField);
  // an infinite pair dies at the global maximum.
  SimplexId birth = -1, death = -1;
  double birth_value = 0, death_value = 0;  // the scalars at birth and death

  bool finite() const { return death_cell >= 0; }
  double Persistence() const { return death_value - birth_value; }
};

struct PersistenceDiagramResult {
  DiscreteGradientResult gradient;
  // Ascending vertex order of the birth vertex (TTK's sort), then type, then death order.
  std::vector<PersistencePair> pairs;
  std::array<int64_t, 3> finite{}, infinite{};  // pairs per type
  // Outputs place the pairs at their vertices instead of (birth, death) (TTK's "embedded in
  // the domain"); set by the caller.
  bool embed_in_domain = false;

  // Largest Persistence() over all pairs (0 without pairs).
  double MaxPersistence() const;
  // "<type> <birth> <death> <finite 1|0>\n" per pair, lines sorted as integer tuples.
  std::string PairsDigest() const;
};

// TTK's persistence curve of one pair type (or every type, type = -1): for each distinct
// persistence p among those pairs, ascending, the number of pairs with persistence >= p.
struct PersistenceCurve {
  std::vector<double> persistence;
  std::vector<int32_t> pairs;
};
PersistenceCurve ComputePersistenceCurve(const PersistenceDiagramResult& diagram, int type);

// The gradient's lower stars (VE, VF, VT). The ascending paths follow what the gradient's sweep
// recorded (AscendingLinks), or on a mesh with crowded triangles find a triangle's tetrahedra in
// the star of its lowest vertex (VT); the boundaries find their edges in the static encoding.
RelationSet PersistenceDiagramDeclared();

// `scalars`: the field by input vertex id, only reported (births, deaths, persistence).
// The gradient, the descending and ascending paths run on every consumer; the union-finds and the
// boundary reduction, sequential as in TTK's reference, on one. `neighbors`: as for
// RunDiscreteGradient, filled by the gradient's pass. `arrays`: the pairings the result's
// gradient keeps, kPaths (vertex -> edge, edge -> triangle), or kPersistence for a caller that
// goes on with the gradient (a simplified complex updates it, then follows its tetrahedron ->
// triangle pairs).
template <TopologicalStructure Structure>
absl::StatusOr<PersistenceDiagramResult> RunPersistenceDiagram(
    Structure& structure, std::span<const SimplexId> order, std::span<const double> scalars,
    const RunContext& context, VertexNeighbors* neighbors = nullptr,
    GradientArrays arrays = GradientArrays::kPaths);

}  // namespace actopo

#endif  // ACTOPO_SERVER_ALGORITHMS_PERSISTENCE_DIAGRAM_H_
