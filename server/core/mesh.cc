#include "server/core/mesh.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <vector>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "server/core/parallel.h"

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
  // Every vertex and tetrahedron is checked in parallel chunks without a branch per item; only
  // a chunk found bad is walked again, item by item, for the message naming the first culprit.
  constexpr int64_t kChunk = 1 << 16;
  const int64_t chunks =
      (std::max<int64_t>(3 * int64_t(nv), 4 * int64_t(nt)) + kChunk - 1) / kChunk;
  std::vector<uint8_t> bad_points(chunks, 0), bad_tets(chunks, 0);
  ParallelFor(chunks, DefaultThreads(), [&](int64_t c, int) {
    const size_t coord_end = std::min(mesh.points.size(), size_t(c + 1) * kChunk);
    bool bad = false;
    for (size_t i = size_t(c) * kChunk; i < coord_end; ++i) bad |= !std::isfinite(mesh.points[i]);
    bad_points[c] = bad;
    bad = false;
    const SimplexId t_end = SimplexId(std::min<int64_t>(nt, (c + 1) * kChunk / 4));
    for (SimplexId t = SimplexId(c * kChunk / 4); t < t_end; ++t) {
      const SimplexId* tv = &mesh.tetrahedra[4 * size_t(t)];
      int culprits = 0;  // ints, not bools: summed without a branch
      for (int k = 0; k < 4; ++k) culprits += int(uint32_t(tv[k]) >= uint32_t(nv));
      culprits += int(tv[0] == tv[1]) + int(tv[0] == tv[2]) + int(tv[0] == tv[3]) +
                  int(tv[1] == tv[2]) + int(tv[1] == tv[3]) + int(tv[2] == tv[3]);
      bad |= culprits != 0;
    }
    bad_tets[c] = bad;
  });
  for (int64_t c = 0; c < chunks; ++c) {
    if (!bad_points[c]) continue;
    for (size_t i = size_t(c) * kChunk; i < std::min(mesh.points.size(), size_t(c + 1) * kChunk);
         ++i) {
      const double x = mesh.points[i];
      if (!std::isfinite(x)) {
        return absl::InvalidArgumentError(absl::StrCat("points: vertex ", i / 3,
                                                       " has a non-finite coordinate ",
                                                       std::string(1, "xyz"[i % 3]), " = ", x));
      }
    }
  }
  for (int64_t c = 0; c < chunks; ++c) {
    if (!bad_tets[c]) continue;
    for (SimplexId t = SimplexId(c * kChunk / 4); t < std::min<int64_t>(nt, (c + 1) * kChunk / 4);
         ++t) {
      const SimplexId* tv = &mesh.tetrahedra[4 * size_t(t)];
      for (int k = 0; k < 4; ++k) {
        if (tv[k] < 0 || tv[k] >= nv) {
          return absl::OutOfRangeError(absl::StrCat(
              "tetrahedra: tetrahedron ", t, " has vertex id ", tv[k], " outside [0, ", nv, ")"));
        }
        for (int j = 0; j < k; ++j) {
          if (tv[j] == tv[k]) {
            return absl::InvalidArgumentError(absl::StrCat(
                "tetrahedra: tetrahedron ", t, " repeats vertex ", tv[k], " (vertices ",
                absl::StrJoin(std::span<const SimplexId>(tv, 4), " "), ")"));
          }
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

absl::StatusOr<int> SelectScalarField(std::span<const PointField* const> fields,
                                      std::string_view name, std::string_view block_label_field) {
  int chosen = -1;
  if (!name.empty()) {
    for (size_t i = 0; i < fields.size(); ++i) {
      if (fields[i]->name == name) chosen = static_cast<int>(i);
    }
    if (chosen < 0) {
      std::vector<std::string> names;
      for (const PointField* f : fields) names.push_back("'" + f->name + "'");
      return absl::NotFoundError(absl::StrCat(
          "scalar field '", std::string(name),
          "' not found; point fields: ", names.empty() ? "none" : absl::StrJoin(names, ", ")));
    }
  } else {
    for (size_t i = 0; i < fields.size(); ++i) {
      if (!fields[i]->is_integer && fields[i]->name != block_label_field) {
        chosen = static_cast<int>(i);
        break;
      }
    }
    if (chosen < 0) {
      return absl::InvalidArgumentError(
          "scalar field: the mesh has no floating-point point field to use as scalar");
    }
  }
  const absl::Status valid = ValidateScalarField(*fields[chosen]);
  if (!valid.ok()) return valid;
  return chosen;
}

absl::StatusOr<int> SelectScalarField(const Mesh& mesh, std::string_view name,
                                      std::string_view block_label_field) {
  std::vector<const PointField*> fields;
  for (const PointField& f : mesh.point_fields) fields.push_back(&f);
  return SelectScalarField(fields, name, block_label_field);
}

}  // namespace actopo
