// discrete-gradient: TTK's DiscreteGradient in 3D, lower-star pairing (Robins, Wood, Sheppard,
// "Theory and algorithms for constructing discrete Morse complexes from grayscale digital
// images"), with TTK's exact cell comparator so the pairs equal TTK's (SEMANTICS.md).
//
//   ASSIGN_OR_RETURN(DiscreteGradientResult g,
//                    RunDiscreteGradient(*structure, order, {.consumers = 2}));
//   g.gradient.IsCritical(1, e);            // internal ids
//   std::string digest = g.PairsDigest(*topology);
#ifndef ACTOPO_SERVER_ALGORITHMS_DISCRETE_GRADIENT_H_
#define ACTOPO_SERVER_ALGORITHMS_DISCRETE_GRADIENT_H_

#include <array>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "server/algorithms/consumers.h"
#include "server/algorithms/vertex_neighbors.h"
#include "server/core/relation.h"
#include "server/core/structures.h"
#include "server/core/topology.h"

namespace actopo {

// The gradient as pairings, in internal ids: up[d][c] is the (d+1)-cell paired with d-cell c,
// down[d][c] the (d-1)-cell paired with d-cell c, -1 when none. The arrays are filled in
// parallel when allocated (the pages first touched on every thread: they are among the largest
// arrays of a Morse-Smale run), hence FilledVector.
using Pairings = FilledVector<SimplexId>;
struct GradientField {
  std::array<Pairings, 4> up;    // d = 0, 1, 2 used
  std::array<Pairings, 4> down;  // d = 1, 2, 3 used

  bool IsCritical(int d, SimplexId c) const {
    return (d == 3 || up[d][c] < 0) && (d == 0 || down[d][c] < 0);
  }
};

struct DiscreteGradientResult {
  GradientField gradient;
  std::array<int64_t, 4> critical_cells{};  // per dimension
  // The critical cells of each dimension, ascending internal id.
  std::array<std::vector<SimplexId>, 4> critical;
  std::array<int64_t, 3> pairs{};  // (0,1), (1,2), (2,3)

  // "<d> <ids>\n" per critical cell, input vertex ids ascending, lines in byte order.
  std::string CriticalCellsDigest(const Topology& topology) const;
  // "<d> <lower ids> <higher ids>\n" per pair, lines in byte order; from either set of arrays.
  std::string PairsDigest(const Topology& topology) const;
};

// Internal vertex ids of a cell, as the static encoding holds them (ascending), into ids[0..d].
void CellVertices(const Topology& topology, int d, SimplexId c, SimplexId* ids);

// Input vertex ids of a cell, ascending, into ids[0..d] (no allocation, for digests).
void CellTokens(const Topology& topology, int d, SimplexId c, SimplexId* ids);

// VE, VF and VT: the lower star of every vertex.
RelationSet DiscreteGradientDeclared();

// Which pairings the result keeps. The persistence pairs follow vertex -> edge, edge -> triangle
// and tetrahedron -> triangle only: without the other three arrays (up[2], down[1], down[2]) the
// gradient takes 4 bytes per edge and 8 per triangle less, and IsCritical answers for d = 0 and 3
// only (`critical` lists every dimension's critical cells). The Morse-Smale complex, whose sweep
// records AscendingLinks, follows vertex -> edge and edge -> triangle only (kPaths: IsCritical
// answers for d = 0; `links->up` takes the place of the tetrahedron -> triangle array).
enum class GradientArrays : uint8_t { kAll, kPersistence, kPaths };

// What the ascending paths (the Morse-Smale complex's separatrices and segmentation, the
// persistence diagram's saddle-maximum pairs) read of the vertex stars, recorded by the
// gradient's sweep while it holds each star. After the sweep, a pass would read every vertex star
// again: on compact and actopo that computes each block's VT a second time. Meshes with crowded
// triangles (three tetrahedra or more) are not supported (Topology::has_crowded_triangles).
struct AscendingLinks {
  // Per tetrahedron paired with a triangle: the other tetrahedron of that triangle, -1 when the
  // triangle is on the boundary. The critical tetrahedra's entries are not written.
  std::span<SimplexId> up;
  // Per vertex: the tetrahedron of its star first in input order, -1 for a vertex in none.
  // Empty: not recorded (the persistence diagram's paths need none).
  std::span<SimplexId> first_tetrahedron;
  // Per consumer (sized by the caller): each critical triangle met, then its tetrahedra,
  // ascending (-1 in the last slot for a triangle on the boundary).
  std::vector<std::vector<std::array<SimplexId, 3>>> saddles;
};

// The 2-saddles' tetrahedra that `links` recorded, two slots per saddle in the order of
// `saddles` (the gradient's critical triangles, ascending id), -1 in the second slot for one on
// the boundary. An internal error if the sweep met other 2-saddles than those.
absl::StatusOr<std::vector<SimplexId>> SaddleTetrahedra(const AscendingLinks& links,
                                                        std::span<const SimplexId> saddles);

// With `neighbors`, each consumer also keeps its blocks' vertex neighbours there, read from the
// VE rows the pairing has just read (a caller whose next passes read VV in no order in space).
// With `links`, the sweep records them.
template <TopologicalStructure Structure>
absl::StatusOr<DiscreteGradientResult> RunDiscreteGradient(
    Structure& structure, std::span<const SimplexId> order, const RunContext& context,
    GradientArrays arrays, VertexNeighbors* neighbors = nullptr, AscendingLinks* links = nullptr);

// The gradient of `order` from `previous`, the gradient of an order in which every two vertices
// not in `reordered` compare as in `order` (a simplified field's order and its input's: LTS moves
// only the vertices it flattens). A cell's pairing depends on its highest vertex's lower star
// alone, so only the stars of the reordered vertices and of their neighbours are paired again.
// The result keeps the arrays `previous` keeps (either set: a pair's two cells lie in one lower
// star, so clearing a star's cells in the kept arrays clears its pairs) and equals
// RunDiscreteGradient(structure, order, context, those arrays), at a fraction of its cost when
// few vertices moved.
// `changed`: when not empty, the vertices whose lower star differs between the two orders,
// ascending and distinct, as a caller that knows both orders and the neighbours found them
// (SimplificationResult::changed_stars): `reordered` and those of their neighbours whose lower
// neighbours moved. Only those stars are paired again, and no VE is read to find them. Without
// it, every neighbour of a reordered vertex is paired again.
template <TopologicalStructure Structure>
absl::StatusOr<DiscreteGradientResult> UpdateDiscreteGradient(
    Structure& structure, DiscreteGradientResult previous, std::span<const SimplexId> order,
    std::span<const SimplexId> reordered, const RunContext& context,
    std::span<const SimplexId> changed = {});

}  // namespace actopo

#endif  // ACTOPO_SERVER_ALGORITHMS_DISCRETE_GRADIENT_H_
