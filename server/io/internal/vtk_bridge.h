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
#include "server/core/progress.h"

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

// While alive, forwards an algorithm's progress events to `progress` as phase `phase` (weighted
// into [from, to] of it), and asks the algorithm to abort once `progress` is stopped. XML readers
// check for the abort between the blocks they decode, so a large read stops within a block.
// After Update, `status()` says whether the output is to be thrown away.
class VtkProgressRelay {
 public:
  VtkProgressRelay(vtkAlgorithm* algorithm, const Progress& progress, std::string_view phase,
                   double from = 0, double to = 1);
  ~VtkProgressRelay();
  VtkProgressRelay(const VtkProgressRelay&) = delete;
  VtkProgressRelay& operator=(const VtkProgressRelay&) = delete;

  absl::Status status() const;

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
