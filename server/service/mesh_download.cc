#include "server/service/mesh_download.h"

#include <algorithm>
#include <cstring>
#include <limits>
#include <set>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"

namespace actopo::service {

// The dtype a field goes back as: the one it came with, unless its values do not fit it (an
// unsigned integer array read as signed); then the next wider one that holds them all.
v1::DataType MeshDownload::DtypeOf(const PointField& field) {
  const auto fits = [&](double lo, double hi) {
    return std::all_of(field.values.begin(), field.values.end(),
                       [&](double v) { return v >= lo && v <= hi; });
  };
  if (field.is_integer) {
    if (field.source_bytes == 4 && fits(-2147483648.0, 2147483647.0)) return v1::DATA_TYPE_INT32;
    // Below 2^63 in magnitude: every double there converts to int64 exactly.
    if (fits(-9223372036854775808.0, 9223372036854774784.0)) return v1::DATA_TYPE_INT64;
    return v1::DATA_TYPE_FLOAT64;
  }
  return field.source_bytes == 4 ? v1::DATA_TYPE_FLOAT32 : v1::DATA_TYPE_FLOAT64;
}

absl::StatusOr<MeshDownload> MeshDownload::Start(std::shared_ptr<const LoadedMesh> mesh,
                                                 const v1::DownloadMeshRequest& request) {
  MeshDownload d;
  const std::vector<FieldSet::Ref> all = mesh->fields.List();
  if (request.all_fields()) {
    if (request.fields_size() > 0) {
      return absl::InvalidArgumentError("fields: give the fields or all_fields, not both");
    }
    d.fields_ = all;
  }
  std::set<std::string> named;
  for (int i = 0; i < request.fields_size(); ++i) {
    const std::string& name = request.fields(i);
    if (!named.insert(name).second) {
      return absl::InvalidArgumentError(
          absl::StrCat("fields[", i, "]: '", name, "' is listed twice"));
    }
    const auto found = std::find_if(all.begin(), all.end(),
                                    [&](const FieldSet::Ref& f) { return f->field.name == name; });
    if (found == all.end()) {
      std::vector<std::string> names;
      for (const FieldSet::Ref& f : all) names.push_back("'" + f->field.name + "'");
      return absl::NotFoundError(
          absl::StrCat("fields[", i, "]: point field '", name, "' not found; point fields: ",
                       names.empty() ? std::string("none") : absl::StrJoin(names, ", ")));
    }
    d.fields_.push_back(*found);
  }
  const Topology& topology = *mesh->topology;
  d.wide_ids_ = topology.num_vertices() > std::numeric_limits<int32_t>::max();
  d.header_.set_name(mesh->name);
  d.header_.set_num_vertices(topology.num_vertices());
  d.header_.set_num_tetrahedra(topology.num_tetrahedra());
  d.header_.set_points_dtype(v1::DATA_TYPE_FLOAT64);
  d.header_.set_tetrahedra_dtype(d.wide_ids_ ? v1::DATA_TYPE_INT64 : v1::DATA_TYPE_INT32);
  for (const FieldSet::Ref& f : d.fields_) {
    v1::UploadField* out = d.header_.add_fields();
    out->set_name(f->field.name);
    out->set_dtype(DtypeOf(f->field));
    if (f->time) out->set_time(*f->time);
  }
  d.mesh_ = std::move(mesh);
  return d;
}

int64_t MeshDownload::count(size_t array) const {
  if (array == 0) return header_.num_vertices();
  if (array == 1) return header_.num_tetrahedra();
  return header_.num_vertices();
}

int MeshDownload::value_bytes(size_t array) const {
  if (array == 0) return 3 * 8;
  if (array == 1) return wide_ids_ ? 4 * 8 : 4 * 4;
  const v1::DataType dtype = header_.fields(int(array - 2)).dtype();
  return dtype == v1::DATA_TYPE_INT32 || dtype == v1::DATA_TYPE_FLOAT32 ? 4 : 8;
}

int64_t MeshDownload::total_bytes() const {
  int64_t bytes = 0;
  for (size_t array = 0; array < 2 + fields_.size(); ++array) {
    bytes += count(array) * value_bytes(array);
  }
  return bytes;
}

bool MeshDownload::Next(size_t max_bytes, std::string* chunk) {
  while (array_ < 2 + fields_.size() && next_ == count(array_)) {
    ++array_;
    next_ = 0;
  }
  if (array_ == 2 + fields_.size()) return false;
  const int size = value_bytes(array_);
  const int64_t n =
      std::min(count(array_) - next_, std::max<int64_t>(1, int64_t(max_bytes) / size));
  chunk->resize(size_t(n) * size_t(size));
  char* out = chunk->data();
  if (array_ == 0) {
    std::memcpy(out, mesh_->mesh.points.data() + 3 * next_, chunk->size());
  } else if (array_ == 1) {
    WriteTetrahedra(next_, n, out);
  } else {
    WriteField(fields_[array_ - 2]->field, header_.fields(int(array_ - 2)).dtype(), next_, n, out);
  }
  next_ += n;
  return true;
}

void MeshDownload::WriteTetrahedra(int64_t first, int64_t count, char* out) const {
  const Topology& topology = *mesh_->topology;
  const std::vector<uint8_t>& corners = *mesh_->input_corners;
  for (int64_t i = first; i < first + count; ++i) {
    const SimplexId t = topology.tetrahedron_internal_id(SimplexId(i));
    const std::array<SimplexId, 4> sorted = topology.tetrahedron(t);
    int64_t given[4];
    for (int k = 0; k < 4; ++k) {
      given[(corners[size_t(t)] >> (2 * k)) & 3] = topology.vertex_input_id(sorted[size_t(k)]);
    }
    for (int k = 0; k < 4; ++k) {
      if (wide_ids_) {
        std::memcpy(out, &given[k], 8);
        out += 8;
      } else {
        const int32_t id = int32_t(given[k]);
        std::memcpy(out, &id, 4);
        out += 4;
      }
    }
  }
}

void MeshDownload::WriteField(const PointField& field, v1::DataType dtype, int64_t first,
                              int64_t count, char* out) const {
  const double* values = field.values.data() + first;
  for (int64_t i = 0; i < count; ++i) {
    switch (dtype) {
      case v1::DATA_TYPE_INT32: {
        const int32_t v = int32_t(values[i]);
        std::memcpy(out + 4 * i, &v, 4);
        break;
      }
      case v1::DATA_TYPE_INT64: {
        const int64_t v = int64_t(values[i]);
        std::memcpy(out + 8 * i, &v, 8);
        break;
      }
      case v1::DATA_TYPE_FLOAT32: {
        const float v = float(values[i]);
        std::memcpy(out + 4 * i, &v, 4);
        break;
      }
      default: std::memcpy(out + 8 * i, &values[i], 8);
    }
  }
}

}  // namespace actopo::service
