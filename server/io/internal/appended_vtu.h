// Private to server/io: a parallel reader for the .vtu layout VTK and ParaView write by default,
// which is nearly every file users bring: one piece, every array in the raw appended section,
// little-endian, uncompressed or zlib-compressed (vtkZLibDataCompressor) in blocks.
//
// VTK's reader inflates those blocks one after another on one core, then the mesh is copied
// out of its arrays. Here the file is mapped, and every block of every array is inflated
// (libdeflate) and converted straight into the Mesh's arrays on all threads, one block per
// task: the cell offsets and types are checked as they stream by and never stored, and no
// whole uncompressed array exists at any time.
//
//   ASSIGN_OR_RETURN(std::optional<Mesh> mesh, internal::ReadAppendedVtu(path, 2, progress));
//   if (!mesh) { /* read it with VTK */ }
//
// It reads what VTK reads, identically (vtk_reader_test compares the two on every shared file):
// points as double, tetrahedra in file order, every 1-component point array as a PointField in
// file order. Anything else (another layout, encoding or compressor, several pieces, cells
// that are not all tetrahedra, ids out of range, a block that does not inflate) gives nullopt,
// and VTK's reader then reads the file and words the error. The mesh returned has passed
// ValidateMesh; its errors are prefixed with the path, as the VTK path's are.
#ifndef ACTOPO_SERVER_IO_INTERNAL_APPENDED_VTU_H_
#define ACTOPO_SERVER_IO_INTERNAL_APPENDED_VTU_H_

#include <optional>
#include <string>

#include "absl/status/statusor.h"
#include "server/core/mesh.h"
#include "server/core/progress.h"

namespace actopo::io::internal {

// Reports phase "read" from 0 to 0.9 and stops (CANCELLED, DEADLINE_EXCEEDED) between windows
// of blocks once `progress` says so.
absl::StatusOr<std::optional<Mesh>> ReadAppendedVtu(const std::string& path, int threads,
                                                    const Progress& progress);

}  // namespace actopo::io::internal

#endif  // ACTOPO_SERVER_IO_INTERNAL_APPENDED_VTU_H_
