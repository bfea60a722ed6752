#include "server/core/mesh.h"

#include <array>
#include <cmath>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"

namespace actopo {

const PointField* Mesh::FindField(std::string_view name) const {
  for (const PointField& f : point_fields) {
    if (f.name == name) return &f;
  }
  return nullptr;
}

absl::Status ValidateMesh(const Mesh& mesh) {
  if (mesh.points.size() % 3 != 0) {
    return absl::InvalidArgumentError(
        absl::StrCat("points: ", mesh.points.size(),
                     " coordinates is not a multiple of 3 (x, y, z per vertex)"));
  }
  if (mesh.tetrahedra.size() % 4 != 0) {
    return absl::InvalidArgumentError(
        absl::StrCat("tetrahedra: ", mesh.tetrahedra.size(), " vertex ids is not a multiple of 4"));
  }
  if (mesh.points.size() / 3 > static_cast<size_t>(INT32_MAX) ||
      mesh.tetrahedra.size() / 4 > static_cast<size_t>(INT32_MAX)) {
    return absl::InvalidArgumentError("mesh: more than 2^31 - 1 vertices or tetrahedra");
  }
  const SimplexId nv = mesh.num_vertices();
  const SimplexId nt = mesh.num_tetrahedra();
  if (nv == 0) return absl::InvalidArgumentError("points: the mesh has no vertices");
  if (nt == 0) return absl::InvalidArgumentError("tetrahedra: the mesh has no tetrahedra");
  for (SimplexId v = 0; v < nv; ++v) {
    for (int k = 0; k < 3; ++k) {
      const double c = mesh.points[3 * size_t(v) + k];
      if (!std::isfinite(c)) {
        return absl::InvalidArgumentError(absl::StrCat("points: vertex ", v,
                                                       " has a non-finite coordinate ",
                                                       std::string(1, "xyz"[k]), " = ", c));
      }
    }
  }
  for (SimplexId t = 0; t < nt; ++t) {
    const SimplexId* tv = &mesh.tetrahedra[4 * size_t(t)];
    for (int k = 0; k < 4; ++k) {
      if (tv[k] < 0 || tv[k] >= nv) {
        return absl::OutOfRangeError(absl::StrCat("tetrahedra: tetrahedron ", t, " has vertex id ",
                                                  tv[k], " outside [0, ", nv, ")"));
      }
      for (int j = 0; j < k; ++j) {
        if (tv[j] == tv[k]) {
          return absl::InvalidArgumentError(
              absl::StrCat("tetrahedra: tetrahedron ", t, " repeats vertex ", tv[k], " (vertices ",
                           absl::StrJoin(std::span<const SimplexId>(tv, 4), " "), ")"));
        }
      }
    }
  }
  for (const PointField& f : mesh.point_fields) {
    if (f.values.size() != static_cast<size_t>(nv)) {
      return absl::InvalidArgumentError(absl::StrCat(
          "point field '", f.name, "' has ", f.values.size(), " values for ", nv, " vertices"));
    }
  }
  return absl::OkStatus();
}

absl::Status ValidateScalarField(const PointField& field) {
  for (size_t v = 0; v < field.values.size(); ++v) {
    if (!std::isfinite(field.values[v])) {
      return absl::InvalidArgumentError(absl::StrCat("point field '", field.name, "': vertex ", v,
                                                     " has non-finite value ", field.values[v]));
    }
  }
  return absl::OkStatus();
}

absl::StatusOr<int> SelectScalarField(const Mesh& mesh, std::string_view name,
                                      std::string_view block_label_field) {
  int chosen = -1;
  if (!name.empty()) {
    for (size_t i = 0; i < mesh.point_fields.size(); ++i) {
      if (mesh.point_fields[i].name == name) chosen = static_cast<int>(i);
    }
    if (chosen < 0) {
      std::vector<std::string> names;
      for (const PointField& f : mesh.point_fields) names.push_back("'" + f.name + "'");
      return absl::NotFoundError(absl::StrCat(
          "scalar field '", std::string(name),
          "' not found; point fields: ", names.empty() ? "none" : absl::StrJoin(names, ", ")));
    }
  } else {
    for (size_t i = 0; i < mesh.point_fields.size(); ++i) {
      const PointField& f = mesh.point_fields[i];
      if (!f.is_integer && f.name != block_label_field) {
        chosen = static_cast<int>(i);
        break;
      }
    }
    if (chosen < 0) {
      return absl::InvalidArgumentError(
          "scalar field: the mesh has no floating-point point field to use as scalar");
    }
  }
  const absl::Status valid = ValidateScalarField(mesh.point_fields[chosen]);
  if (!valid.ok()) return valid;
  return chosen;
}

}  // namespace actopo
