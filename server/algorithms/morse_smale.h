// morse-smale: TTK's MorseSmaleComplex in 3D with its defaults (SEMANTICS.md): critical points,
// descending and ascending 1-separatrices, saddle connectors and the descending, ascending and
// Morse-Smale segmentations; no 2-separatrices, no simplification.
//
//   ASSIGN_OR_RETURN(std::vector<uint8_t> corners, InputCorners(*topology, mesh.tetrahedra));
//   ASSIGN_OR_RETURN(MorseSmaleResult ms,
//                    RunMorseSmale(*structure, order, corners, {.consumers = 2}));
//   ms.descending[v];   // DescendingManifold of input vertex v
//
// Where TTK's traversal order decides (the first other tetrahedron of a triangle's star, the
// last wall triangle around an edge), the choice follows TTK's explicit triangulation order,
// computed from input ids, so results do not depend on the partition or the structure.
#ifndef ACTOPO_SERVER_ALGORITHMS_MORSE_SMALE_H_
#define ACTOPO_SERVER_ALGORITHMS_MORSE_SMALE_H_

#include <array>
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "server/algorithms/consumers.h"
#include "server/algorithms/discrete_gradient.h"
#include "server/core/relation.h"
#include "server/core/structures.h"

namespace actopo {

// TTK's SeparatrixType codes.
enum class SeparatrixType : int8_t { kDescending = 0, kSaddleConnector = 1, kAscending = 2 };

struct Cell {
  int8_t dim;
  SimplexId id;  // internal id
};

struct Separatrix {
  SeparatrixType type;
  Cell source;       // the saddle (1-saddle for connectors)
  Cell destination;  // the extremum (2-saddle for connectors)
  // The V-path's cell ids, source first. Its cells' dimensions alternate: the source's at even
  // positions, one below it (descending) or above it (ascending, connectors) at odd ones, so
  // only the ids are kept (4 bytes each instead of 8); cell(i) gives both.
  std::vector<SimplexId> path;

  int8_t dimension(size_t i) const {
    if (i % 2 == 0) return source.dim;
    return type == SeparatrixType::kDescending ? int8_t(source.dim - 1) : int8_t(source.dim + 1);
  }
  Cell cell(size_t i) const { return {dimension(i), path[i]}; }
};

struct MorseSmaleResult {
  // The gradient's lists (critical cells, counts); its pairing arrays are freed once the complex
  // no longer reads them.
  DiscreteGradientResult gradient;
  std::vector<Separatrix> separatrices;  // descending, then ascending, then saddle connectors
  // Per input vertex: DescendingManifold, AscendingManifold, MorseSmaleManifold.
  std::vector<SimplexId> descending, ascending, morse_smale;
  // ManifoldSize of each minimum (ascending vertex id) and maximum (ascending tetrahedron id).
  std::vector<int64_t> minimum_sizes, maximum_sizes;

  int64_t CountSeparatrices(SeparatrixType type) const;
  int64_t Segments() const;  // polyline segments over all separatrices
  // Distinct values of a per-vertex array (-1 included when present).
  static int64_t Regions(std::span<const SimplexId> labels);
  // "<vertex id> <label>\n" per vertex, ascending id.
  static std::string SegmentationDigest(std::span<const SimplexId> labels);
};

// The gradient's lower stars (VE, VF, VT). The ascending paths find a triangle's tetrahedra in
// its lowest vertex's star (VT); the descending walls of saddle connectors read no relation:
// their triangles' edges come from the static encoding, and the walls themselves say which of
// their triangles lie around an edge.
RelationSet MorseSmaleDeclared();

// TTK numbers triangles by their first appearance over the tetrahedra as given, so it depends on
// the order each tetrahedron's vertices came in. InputCorners keeps just that: per internal
// tetrahedron t one byte, whose bits 2k..2k+1 are the position, in t as given, of corner k of
// its sorted tuple (topology.tetrahedron(t)[k]). One byte instead of the mesh's 16.
// INVALID_ARGUMENT when `input_tetrahedra` (4 input vertex ids each) is not the topology's mesh.
absl::StatusOr<std::vector<uint8_t>> InputCorners(const Topology& topology,
                                                  std::span<const SimplexId> input_tetrahedra);

// `input_corners`: InputCorners of the mesh. `gradient`: the gradient of `order`, either set of
// arrays, when the caller has it already (a simplified field's, from UpdateDiscreteGradient);
// computed otherwise. The result's gradient keeps the critical cells, not the pairing arrays.
// Everything that reads relations runs on all consumers: the gradient and the
// ascending segmentation by blocks, the separatrices by 2-saddle.
template <TopologicalStructure Structure>
absl::StatusOr<MorseSmaleResult> RunMorseSmale(
    Structure& structure, std::span<const SimplexId> order, std::span<const uint8_t> input_corners,
    const RunContext& context, std::optional<DiscreteGradientResult> gradient = std::nullopt);

}  // namespace actopo

#endif  // ACTOPO_SERVER_ALGORITHMS_MORSE_SMALE_H_
