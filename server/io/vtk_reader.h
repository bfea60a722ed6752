// Reads tetrahedral meshes from VTK files into an actopo::Mesh.
//
// Supported inputs, chosen by extension (case-insensitive):
//   .vtu  VTK XML unstructured grid;
//   .vtk  legacy VTK unstructured grid (ASCII or binary);
//   .vti  VTK XML image data, split into tetrahedra by VTK's vtkDataSetTriangleFilter, which is
//         ParaView's Tetrahedralize (5 tetrahedra per voxel), so ids match what ParaView shows.
// A .vtu in the layout VTK writes by default is read on every core; any other goes to VTK's
// reader, with the same result. Only tetrahedral cells are accepted. Every 1-component point array
// becomes a PointField; vector and tensor arrays are skipped. The result has passed
// actopo::ValidateMesh.
//
//   ASSIGN_OR_RETURN(actopo::Mesh mesh, actopo::io::ReadMesh("/data/fertility_tet.vtu"));
//
// Errors: NotFound when the file does not exist; InvalidArgument for an unsupported extension, a
// file VTK cannot read, non-tetrahedral cells or an invalid mesh. Messages start with the path.
// With a `progress`, reading reports phase "read" and stops (CANCELLED or DEADLINE_EXCEEDED)
// within one decoded block of the file once `progress` says so.
#ifndef ACTOPO_SERVER_IO_VTK_READER_H_
#define ACTOPO_SERVER_IO_VTK_READER_H_

#include <string>

#include "absl/status/statusor.h"
#include "server/core/mesh.h"
#include "server/core/progress.h"

namespace actopo::io {

struct ReadOptions {
  // Threads that inflate and convert a .vtu's blocks (0: every core).
  int threads = 0;
  // .vtu files in the layout VTK writes by default (one piece, raw appended arrays, zlib or
  // uncompressed) are read by our parallel reader (internal/appended_vtu.h); false reads every
  // file with VTK's own reader, the reference the parallel one is tested against.
  bool parallel_vtu = true;
};

// The VTK library version, e.g. "9.1.0" (for server info).
std::string VtkVersion();

absl::StatusOr<Mesh> ReadMesh(const std::string& path, const ReadOptions& options = {},
                              const Progress& progress = {});

}  // namespace actopo::io

#endif  // ACTOPO_SERVER_IO_VTK_READER_H_
