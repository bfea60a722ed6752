// Writes meshes and results as VTK XML files for ParaView (binary appended, zlib-compressed).
//
// Array names and types follow TTK's outputs (e.g. "CriticalType" as int8), so that ParaView
// state files built for TTK apply unchanged.
//
//   std::vector<actopo::io::NamedArray> extra = {{"CriticalType", std::vector<int8_t>(n, 0)}};
//   RETURN_IF_ERROR(actopo::io::WriteUnstructuredGrid("/tmp/out.vtu", mesh, extra));
//
//   actopo::io::PolyData critical_points;   // no lines: every point becomes a vertex cell
//   critical_points.points = {0, 0, 0, 1, 0, 0};
//   critical_points.point_arrays.push_back({"CriticalType", std::vector<int8_t>{0, 3}});
//   RETURN_IF_ERROR(actopo::io::WritePolyData("/tmp/critical_points.vtp", critical_points));
//
// Errors: InvalidArgument for a wrong extension, a malformed mesh or poly data, or an array whose
// length does not match (the message names the array); NotFound when the output directory does
// not exist; PermissionDenied or Internal when VTK cannot write the file (the message names it).
#ifndef ACTOPO_SERVER_IO_VTK_WRITER_H_
#define ACTOPO_SERVER_IO_VTK_WRITER_H_

#include <cstddef>
#include <cstdint>
#include <span>
#include <string>
#include <variant>
#include <vector>

#include "absl/status/status.h"
#include "server/core/mesh.h"

namespace actopo::io {

// One value per point (or per cell). The alternatives map to vtkIntArray (Int32),
// vtkSignedCharArray (Int8), vtkDoubleArray (Float64) and vtkFloatArray (Float32).
struct NamedArray {
  using Values = std::variant<std::vector<int32_t>, std::vector<int8_t>, std::vector<double>,
                              std::vector<float>>;

  std::string name;
  Values values;
  int components = 1;  // values per tuple, e.g. 3 for TTK's Coordinates

  // Tuples: one per point (or cell).
  size_t size() const {
    return std::visit([](const auto& v) { return v.size(); }, values) / size_t(components);
  }
};

// Points with optional polylines, e.g. critical points or separatrices.
struct PolyData {
  std::vector<double> points;  // x, y, z per point
  // Polylines in VTK's offsets form: line i is line_connectivity[line_offsets[i] ..
  // line_offsets[i + 1]), so line_offsets has one entry more than there are lines and starts at 0.
  // With no lines (both empty), every point is written as a vertex cell so ParaView shows it.
  std::vector<int32_t> line_offsets;
  std::vector<int32_t> line_connectivity;
  std::vector<NamedArray> point_arrays;  // one value per point
  std::vector<NamedArray> cell_arrays;   // one value per line, or per point when there are no lines
};

// Writes `mesh` as a .vtu file: its tetrahedra, every point field (Float64, or Int32 when
// is_integer and all values fit) and `extra_point_arrays` (one value per vertex each).
absl::Status WriteUnstructuredGrid(const std::string& path, const Mesh& mesh,
                                   std::span<const NamedArray> extra_point_arrays = {});

// Writes `poly_data` as a .vtp file, or as a .vtu file (an unstructured grid of line cells, as
// TTK's persistence diagrams are) when the path ends in .vtu.
absl::Status WritePolyData(const std::string& path, const PolyData& poly_data);

}  // namespace actopo::io

#endif  // ACTOPO_SERVER_IO_VTK_WRITER_H_
