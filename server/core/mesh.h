// The mesh as loaded or uploaded: points, tetrahedra and named point fields, in input ids.
//
// Every other part of the core works on a validated Mesh:
//
//   actopo::Mesh mesh = ...;                       // from server/io or an upload
//   RETURN_IF_ERROR(actopo::ValidateMesh(mesh));
//   ASSIGN_OR_RETURN(int field, actopo::SelectScalarField(mesh, "height"));
#ifndef ACTOPO_SERVER_CORE_MESH_H_
#define ACTOPO_SERVER_CORE_MESH_H_

#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"

namespace actopo {

// Ids of vertices, edges, triangles and tetrahedra. 32 bits hold meshes of up to 2^31 - 1
// simplices per dimension, far beyond what fits in memory for triangles of such meshes anyway.
using SimplexId = int32_t;

// A named per-vertex array. Values are stored as double (exact for float32 and int32 inputs);
// `is_integer` remembers whether the source array was integral (e.g. a block-label array).
struct PointField {
  std::string name;
  std::vector<double> values;
  bool is_integer = false;
  // Bytes per value of the source array (4: float32/int32, 8: float64/int64), so clients can be
  // told the type the field had as loaded.
  int8_t source_bytes = 8;
  // A series member's time value (a .pvd step's timestep, or given when the field was added).
  std::optional<double> time;
};

struct Mesh {
  std::vector<double> points;         // x, y, z per vertex
  std::vector<SimplexId> tetrahedra;  // 4 vertex ids per tetrahedron, as given
  std::vector<PointField> point_fields;

  SimplexId num_vertices() const { return static_cast<SimplexId>(points.size() / 3); }
  SimplexId num_tetrahedra() const { return static_cast<SimplexId>(tetrahedra.size() / 4); }

  // The field called `name`, or nullptr.
  const PointField* FindField(std::string_view name) const;
};

// Checks the mesh is a non-empty set of tetrahedra over its points: array lengths, vertex ids in
// range, no repeated vertex in a tetrahedron, finite coordinates, and one value per vertex in every
// point field. The message names the first offending tetrahedron or vertex and its value.
absl::Status ValidateMesh(const Mesh& mesh);

// Checks that one field has only finite values (NaN and infinities cannot be ordered).
absl::Status ValidateScalarField(const PointField& field);

// The index in mesh.point_fields of the scalar field to use: the one called `name`, or when
// `name` is empty the first floating-point field that is not `block_label_field`. The field is
// validated (finite values).
absl::StatusOr<int> SelectScalarField(const Mesh& mesh, std::string_view name,
                                      std::string_view block_label_field = {});
// The same choice among `fields` (a mesh's fields held elsewhere): the index in `fields`.
absl::StatusOr<int> SelectScalarField(std::span<const PointField* const> fields,
                                      std::string_view name,
                                      std::string_view block_label_field = {});

}  // namespace actopo

#endif  // ACTOPO_SERVER_CORE_MESH_H_
