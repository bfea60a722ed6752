#include "server/service/upload_decoder.h"

#include <cstdint>
#include <cstring>
#include <string>

#include "absl/strings/str_cat.h"
#include "server/algorithms/digest.h"
#include "server/core/status_macros.h"
#include "server/service/wire.h"

namespace actopo::service {
namespace {

template <class T>
T Read(const char* p) {
  T v;
  std::memcpy(&v, p, sizeof(T));
  return v;
}

bool IsFieldType(v1::DataType t) {
  return t == v1::DATA_TYPE_FLOAT32 || t == v1::DATA_TYPE_FLOAT64 || t == v1::DATA_TYPE_INT32 ||
         t == v1::DATA_TYPE_INT64;
}

}  // namespace

absl::StatusOr<size_t> CheckUploadHeader(const v1::UploadMeshHeader& header) {
  const int64_t nv = header.num_vertices(), nt = header.num_tetrahedra();
  if (nv <= 0 || nv > INT32_MAX) {
    return absl::InvalidArgumentError(
        absl::StrCat("header.num_vertices: ", nv, " is outside [1, 2^31 - 1]"));
  }
  if (nt <= 0 || nt > INT32_MAX) {
    return absl::InvalidArgumentError(
        absl::StrCat("header.num_tetrahedra: ", nt, " is outside [1, 2^31 - 1]"));
  }
  if (header.points_dtype() != v1::DATA_TYPE_FLOAT32 &&
      header.points_dtype() != v1::DATA_TYPE_FLOAT64) {
    return absl::InvalidArgumentError(
        absl::StrCat("header.points_dtype: ", v1::DataType_Name(header.points_dtype()),
                     " is not FLOAT32 or FLOAT64"));
  }
  if (header.tetrahedra_dtype() != v1::DATA_TYPE_INT32 &&
      header.tetrahedra_dtype() != v1::DATA_TYPE_INT64) {
    return absl::InvalidArgumentError(
        absl::StrCat("header.tetrahedra_dtype: ", v1::DataType_Name(header.tetrahedra_dtype()),
                     " is not INT32 or INT64"));
  }
  size_t bytes = size_t(nv) * 3 * DataTypeSize(header.points_dtype()) +
                 size_t(nt) * 4 * DataTypeSize(header.tetrahedra_dtype());
  for (int i = 0; i < header.fields_size(); ++i) {
    const v1::UploadField& f = header.fields(i);
    if (f.name().empty()) {
      return absl::InvalidArgumentError(absl::StrCat("header.fields[", i, "].name: empty"));
    }
    if (!IsFieldType(f.dtype())) {
      const std::string name = v1::DataType_Name(f.dtype());
      return absl::InvalidArgumentError(absl::StrCat(
          "header.fields[", i, "].dtype: ", name.empty() ? std::to_string(int(f.dtype())) : name,
          " is not FLOAT32, FLOAT64, INT32 or INT64"));
    }
    bytes += size_t(nv) * DataTypeSize(f.dtype());
  }
  if (header.sha256().size() != 64) {
    return absl::InvalidArgumentError(
        "header.sha256: expected 64 lowercase hex digits (SHA-256 of all array bytes)");
  }
  return bytes;
}

absl::StatusOr<Mesh> DecodeUpload(const v1::UploadMeshHeader& header, std::string_view data) {
  ASSIGN_OR_RETURN(const size_t expected, CheckUploadHeader(header));
  if (data.size() != expected) {
    return absl::InvalidArgumentError(absl::StrCat("chunk: the upload ended after ", data.size(),
                                                   " of ", expected, " bytes (truncated)"));
  }
  const std::string digest = Sha256Hex(data);
  if (digest != header.sha256()) {
    return absl::DataLossError(absl::StrCat("header.sha256: the data hashes to ", digest, ", not ",
                                            header.sha256(), " (corrupted upload)"));
  }
  Mesh mesh;
  const int64_t nv = header.num_vertices(), nt = header.num_tetrahedra();
  const char* p = data.data();
  mesh.points.resize(size_t(nv) * 3);
  const bool f32 = header.points_dtype() == v1::DATA_TYPE_FLOAT32;
  for (size_t i = 0; i < mesh.points.size(); ++i) {
    mesh.points[i] = f32 ? Read<float>(p + 4 * i) : Read<double>(p + 8 * i);
  }
  p += mesh.points.size() * (f32 ? 4 : 8);
  mesh.tetrahedra.resize(size_t(nt) * 4);
  const bool i32 = header.tetrahedra_dtype() == v1::DATA_TYPE_INT32;
  for (size_t i = 0; i < mesh.tetrahedra.size(); ++i) {
    const int64_t v = i32 ? Read<int32_t>(p + 4 * i) : Read<int64_t>(p + 8 * i);
    if (v < 0 || v >= nv) {
      return absl::OutOfRangeError(absl::StrCat("tetrahedra: tetrahedron ", i / 4,
                                                " has vertex id ", v, " outside [0, ", nv, ")"));
    }
    mesh.tetrahedra[i] = SimplexId(v);
  }
  p += mesh.tetrahedra.size() * (i32 ? 4 : 8);
  for (const v1::UploadField& f : header.fields()) {
    PointField field{f.name(), std::vector<double>(nv)};
    field.is_integer = f.dtype() == v1::DATA_TYPE_INT32 || f.dtype() == v1::DATA_TYPE_INT64;
    field.source_bytes = int8_t(DataTypeSize(f.dtype()));
    for (int64_t i = 0; i < nv; ++i) {
      switch (f.dtype()) {
        case v1::DATA_TYPE_FLOAT32: field.values[i] = Read<float>(p + 4 * i); break;
        case v1::DATA_TYPE_FLOAT64: field.values[i] = Read<double>(p + 8 * i); break;
        case v1::DATA_TYPE_INT32: field.values[i] = Read<int32_t>(p + 4 * i); break;
        default: field.values[i] = double(Read<int64_t>(p + 8 * i)); break;
      }
    }
    p += size_t(nv) * DataTypeSize(f.dtype());
    mesh.point_fields.push_back(std::move(field));
  }
  return mesh;
}

}  // namespace actopo::service
