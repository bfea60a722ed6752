#include "server/io/cell_types.h"

#include <map>
#include <string>
#include <vector>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"

namespace actopo::io {

std::string_view VtkCellTypeName(int vtk_cell_type) {
  switch (vtk_cell_type) {
    case 0: return "empty cell";
    case 1: return "vertex";
    case 2: return "poly-vertex";
    case 3: return "line";
    case 4: return "poly-line";
    case 5: return "triangle";
    case 6: return "triangle strip";
    case 7: return "polygon";
    case 8: return "pixel";
    case 9: return "quad";
    case 10: return "tetrahedron";
    case 11: return "voxel";
    case 12: return "hexahedron";
    case 13: return "wedge";
    case 14: return "pyramid";
    case 15: return "pentagonal prism";
    case 16: return "hexagonal prism";
    default: return vtk_cell_type < 30 ? "quadratic cell" : "higher-order or polyhedral cell";
  }
}

absl::Status ValidateCellTypes(std::span<const uint8_t> vtk_cell_types) {
  constexpr int kTetra = 10;
  std::map<int, int64_t> found;
  for (uint8_t t : vtk_cell_types) {
    if (t != kTetra) ++found[t];
  }
  if (found.empty()) return absl::OkStatus();
  std::vector<std::string> parts;
  for (const auto& [type, count] : found) {
    parts.push_back(
        absl::StrCat(count, " ", std::string(VtkCellTypeName(type)), " (VTK type ", type, ")"));
  }
  const bool surface_only =
      found.size() == 1 && (found.begin()->first == 5 || found.begin()->first == 9);
  return absl::InvalidArgumentError(absl::StrCat(
      "cells: only tetrahedral meshes are served; found ", absl::StrJoin(parts, ", "),
      surface_only ? " (a 2D surface mesh; fill its volume, e.g. with TetGen, first)"
                   : " (ParaView's Tetrahedralize filter splits 3D cells into tetrahedra)"));
}

}  // namespace actopo::io
