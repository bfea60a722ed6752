// Private to server/io: the VTK-facing pieces shared by the reader, the writer and the samples.
//
// Only forward declarations of VTK classes appear here, so including this header pulls no VTK
// header into a translation unit; the definitions live in vtk_bridge.cc.
//
//   internal::VtkErrorCollector errors(reader);
//   reader->Update();
//   if (errors.has_error()) return absl::InvalidArgumentError(errors.message());
//   ASSIGN_OR_RETURN(Mesh mesh, internal::UnstructuredGridToMesh(*reader->GetOutput()));
#ifndef ACTOPO_SERVER_IO_INTERNAL_VTK_BRIDGE_H_
#define ACTOPO_SERVER_IO_INTERNAL_VTK_BRIDGE_H_

#include <memory>
#include <string>

#include "absl/status/statusor.h"
#include "server/core/mesh.h"

class vtkAlgorithm;
class vtkUnstructuredGrid;

namespace actopo::io::internal {

// While alive, catches the error and warning events of an algorithm and of its executive, which
// VTK would otherwise print to stderr, and keeps the error texts. VTK readers report most
// failures only this way, not through a return value.
class VtkErrorCollector {
 public:
  explicit VtkErrorCollector(vtkAlgorithm* algorithm);
  ~VtkErrorCollector();
  VtkErrorCollector(const VtkErrorCollector&) = delete;
  VtkErrorCollector& operator=(const VtkErrorCollector&) = delete;

  bool has_error() const;
  // The error texts joined by "; ", without VTK's source-file and object-address prefixes.
  std::string message() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// Converts a grid of tetrahedra: points as double, tetrahedra in file order with their vertex
// order kept, every 1-component point array as a PointField. Reads the cell arrays directly
// (no per-cell virtual calls). Refuses other cell types (ValidateCellTypes), ids beyond int32 and
// meshes that fail ValidateMesh.
absl::StatusOr<Mesh> UnstructuredGridToMesh(vtkUnstructuredGrid& grid);

}  // namespace actopo::io::internal

#endif  // ACTOPO_SERVER_IO_INTERNAL_VTK_BRIDGE_H_
