// Algorithm results as VTK files for ParaView, with TTK's array names:
//   PREFIX_critical_points.vtp   critical points (critical-points, morse-smale)
//   PREFIX_critical_cells.vtp    critical cells at their barycentres (discrete-gradient)
//   PREFIX_separatrices.vtp      1-separatrices as polylines (morse-smale)
//   PREFIX_segmentation.vtu      the mesh with the three manifold arrays (morse-smale)
#ifndef ACTOPO_SERVER_CMD_RESULT_FILES_H_
#define ACTOPO_SERVER_CMD_RESULT_FILES_H_

#include <span>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "server/algorithms/critical_points.h"
#include "server/algorithms/discrete_gradient.h"
#include "server/algorithms/morse_smale.h"
#include "server/core/mesh.h"
#include "server/core/topology.h"

namespace actopo {

// What every writer needs: the mesh as loaded (points, tetrahedra), the scalar field used and
// a per-internal-vertex boundary flag.
struct ResultContext {
  const Mesh& mesh;
  const Topology& topology;
  std::string scalar_name;
  std::span<const double> scalars;         // by input vertex id
  std::vector<uint8_t> vertex_on_boundary;  // by internal vertex id
};

// The files written, for the caller to print.
absl::StatusOr<std::vector<std::string>> WriteCriticalPointsFiles(
    const std::string& prefix, const ResultContext& context, const CriticalPointsResult& r);
absl::StatusOr<std::vector<std::string>> WriteDiscreteGradientFiles(
    const std::string& prefix, const ResultContext& context, const DiscreteGradientResult& r);
absl::StatusOr<std::vector<std::string>> WriteMorseSmaleFiles(
    const std::string& prefix, const ResultContext& context, const MorseSmaleResult& r);

}  // namespace actopo

#endif  // ACTOPO_SERVER_CMD_RESULT_FILES_H_
