// Algorithm results as arrays and VTK files for ParaView, with TTK's array names:
//   PREFIX_critical_points.vtp   critical points (critical-points, morse-smale)
//   PREFIX_critical_cells.vtp    critical cells at their barycentres (discrete-gradient)
//   PREFIX_separatrices.vtp      1-separatrices as polylines (morse-smale)
//   PREFIX_segmentation.vtu      the mesh with the three manifold arrays (morse-smale), or each
//                                vertex's arc: SegmentationId, RegionSize, RegionSpan,
//                                RegionType (merge-tree, contour-tree)
//   PREFIX_tree_nodes.vtp        a tree's nodes: NodeId, Scalar, VertexId, CriticalType,
//                                RegionSize, RegionSpan (merge-tree, contour-tree)
//   PREFIX_tree_arcs.vtp         its arcs as lines: SegmentationId, upNodeId, downNodeId,
//                                RegionSize, RegionSpan (per line), Scalar (per point)
//   PREFIX_diagram.vtu           the persistence diagram, TTK's grid (persistence-diagram)
//   PREFIX_persistence_curve.csv pairs alive above each persistence, per type (persistence-diagram)
//   PREFIX_simplified.vtu        the mesh with the simplified field and its order
//                                (topological-simplification, morse-smale and the trees with a
//                                threshold)
#ifndef ACTOPO_SERVER_RESULTS_RESULT_FILES_H_
#define ACTOPO_SERVER_RESULTS_RESULT_FILES_H_

#include <memory>
#include <span>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "server/core/mesh.h"
#include "server/core/topology.h"
#include "server/io/vtk_writer.h"
#include "server/results/run_algorithm.h"
#include "server/results/vertex_boundary.h"

namespace actopo {

// What every writer needs: the mesh as loaded (points, tetrahedra), the scalar field used and
// the vertices' boundary flags.
struct ResultContext {
  const Mesh& mesh;
  const Topology& topology;
  std::string scalar_name;
  std::span<const double> scalars;  // by input vertex id
  std::shared_ptr<const VertexBoundary> vertex_on_boundary;
  // The vertex order by input id when it is not (scalar, id): a simplified field's, whose
  // flattened plateaus are ordered by LTS. Empty: (scalar, id).
  std::span<const SimplexId> order = {};
};

// A result's outputs: poly data by group ("critical_points", "critical_cells",
// "separatrices") and per-vertex arrays ("segmentation"), with TTK's array names. The service
// streams them as "<group>/<name>" arrays; WriteResultFiles writes them for ParaView.
struct ResultOutputs {
  std::vector<std::pair<std::string, io::PolyData>> poly_data;
  std::vector<io::NamedArray> segmentation;  // one value per input vertex
  // The simplified field and its order, one value per input vertex (topological-simplification,
  // morse-smale with a threshold), under the field's name and "<field>_Order".
  std::vector<io::NamedArray> simplified;
  // Tables ("persistence_curve"): columns of equal length.
  std::vector<std::pair<std::string, std::vector<io::NamedArray>>> tables;
};
ResultOutputs BuildOutputs(const ResultContext& context, const AlgorithmResult& result);

// The input vertex ids of cell `c` of dimension `d` (internal id), ascending: where outputs
// place a cell and what they report of it.
std::vector<SimplexId> CellInputVertices(const Topology& topology, int d, SimplexId c);

// Writes PREFIX_<group>.vtp for each poly data group (.vtu for the diagram), PREFIX_<table>.csv
// for each table and PREFIX_segmentation.vtu; returns the paths written.
absl::StatusOr<std::vector<std::string>> WriteResultFiles(const std::string& prefix,
                                                          const ResultContext& context,
                                                          const AlgorithmResult& result);

}  // namespace actopo

#endif  // ACTOPO_SERVER_RESULTS_RESULT_FILES_H_
