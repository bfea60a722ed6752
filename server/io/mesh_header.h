// The size a mesh file announces in its header, read without loading the file, so a server can
// refuse a mesh that would not fit its memory budget before allocating anything for it.
//
//   ASSIGN_OR_RETURN(actopo::io::MeshCounts counts, actopo::io::ReadMeshCounts(path));
//   RETURN_IF_ERROR(budget.Reserve(EstimateBytes(counts.vertices, counts.tetrahedra), ...));
//
// .vtu: the NumberOfPoints and NumberOfCells of its Piece elements (summed); cells are counted
//       as tetrahedra (other cell types are refused later, when read).
// .vti: the WholeExtent, split as ReadMesh does (5 tetrahedra per voxel).
// .vtk: the POINTS and CELLS lines of a legacy file; binary sections are skipped by their size,
//       ASCII ones by lines.
// Counts come from the file's own claims: a file may lie, and ReadMesh remains the judge of
// what it holds. NotFound when the file does not exist, InvalidArgument when no counts can be
// read (the caller then falls back to a bound from the file size).
#ifndef ACTOPO_SERVER_IO_MESH_HEADER_H_
#define ACTOPO_SERVER_IO_MESH_HEADER_H_

#include <cstdint>
#include <string>
#include <vector>

#include "absl/status/statusor.h"

namespace actopo::io {

struct MeshCounts {
  int64_t vertices = 0;
  int64_t tetrahedra = 0;
  int point_fields = 0;  // scalar point arrays announced (.vtu and .vti; 0 when unknown)
};

absl::StatusOr<MeshCounts> ReadMeshCounts(const std::string& path);

// A series' counts (collection.h): the first file's points and tetrahedra, every file's fields.
absl::StatusOr<MeshCounts> ReadSeriesCounts(const std::vector<std::string>& files);

}  // namespace actopo::io

#endif  // ACTOPO_SERVER_IO_MESH_HEADER_H_
