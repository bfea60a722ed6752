// The VTK cell type codes of an input mesh: their names, and the check that a mesh holds only
// tetrahedra. The readers run it on every file before copying its cells.
//
//   RETURN_IF_ERROR(actopo::io::ValidateCellTypes(cell_types));   // VTK_TETRA = 10 only
#ifndef ACTOPO_SERVER_IO_CELL_TYPES_H_
#define ACTOPO_SERVER_IO_CELL_TYPES_H_

#include <cstdint>
#include <span>
#include <string_view>

#include "absl/status/status.h"

namespace actopo::io {

// Checks VTK cell type codes: all must be tetrahedra (VTK_TETRA = 10). Otherwise the error lists
// every cell type found with its count, e.g. "found 36290 triangle (VTK type 5)".
absl::Status ValidateCellTypes(std::span<const uint8_t> vtk_cell_types);

// Human name of a VTK linear cell type code ("triangle", "hexahedron", ...).
std::string_view VtkCellTypeName(int vtk_cell_type);

}  // namespace actopo::io

#endif  // ACTOPO_SERVER_IO_CELL_TYPES_H_
