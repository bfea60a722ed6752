// Client::DownloadMesh: the header's vectors are sized once, then each chunk's values are
// converted into them as the chunk arrives (a value cut between two chunks is carried over to
// the next), so the mesh's bytes are never held whole.
#include <algorithm>
#include <cstring>
#include <initializer_list>
#include <variant>

#include "absl/strings/str_cat.h"
#include "actopo/client.h"
#include "src/internal/core.h"
#include "src/internal/names.h"

namespace actopo::client {
namespace {

template <class In, class Out>
void Convert(const char* in, size_t n, Out* out) {
  for (size_t i = 0; i < n; ++i) {
    In value;
    std::memcpy(&value, in + i * sizeof(In), sizeof(In));
    out[i] = static_cast<Out>(value);
  }
}

// `n` little-endian values of `dtype` (one of the four the header may announce) into `out`.
template <class Out>
void ConvertAny(DataType dtype, const char* in, size_t n, Out* out) {
  switch (dtype) {
    case DataType::kFloat32: return Convert<float>(in, n, out);
    case DataType::kFloat64: return Convert<double>(in, n, out);
    case DataType::kInt32: return Convert<int32_t>(in, n, out);
    case DataType::kInt64: return Convert<int64_t>(in, n, out);
    default: return;  // refused with the header
  }
}

// The stream's arrays one after the other: points, tetrahedra, then each field.
class Decoder {
 public:
  absl::Status Start(const v1::UploadMeshHeader& header, MeshArrays& mesh) {
    if (started_) return absl::DataLossError("DownloadMesh: a second header");
    started_ = true;
    if (header.num_vertices() < 0 || header.num_tetrahedra() < 0) {
      return absl::DataLossError(absl::StrCat("DownloadMesh: ", header.num_vertices(),
                                              " vertices and ", header.num_tetrahedra(),
                                              " tetrahedra in the header"));
    }
    const size_t vertices = size_t(header.num_vertices());
    mesh.name = header.name();
    mesh.points.resize(3 * vertices);
    mesh.tetrahedra.resize(4 * size_t(header.num_tetrahedra()));
    mesh.fields.resize(size_t(header.fields_size()));
    ACTOPO_RETURN_IF_ERROR(Add("points", header.points_dtype(),
                               {DataType::kFloat32, DataType::kFloat64}, mesh.points.data(),
                               mesh.points.size()));
    ACTOPO_RETURN_IF_ERROR(Add("tetrahedra", header.tetrahedra_dtype(),
                               {DataType::kInt32, DataType::kInt64}, mesh.tetrahedra.data(),
                               mesh.tetrahedra.size()));
    for (int i = 0; i < header.fields_size(); ++i) {
      const v1::UploadField& f = header.fields(i);
      MeshField& field = mesh.fields[size_t(i)];
      field.name = f.name();
      field.dtype = internal::FromProto(f.dtype());
      if (f.has_time()) field.time = f.time();
      field.values.resize(vertices);
      ACTOPO_RETURN_IF_ERROR(
          Add(absl::StrCat("field '", f.name(), "'"), f.dtype(),
              {DataType::kFloat32, DataType::kFloat64, DataType::kInt32, DataType::kInt64},
              field.values.data(), vertices));
    }
    return absl::OkStatus();
  }

  absl::Status Take(std::string_view bytes) {
    if (!started_) return absl::DataLossError("DownloadMesh: a chunk before the header");
    received_ += int64_t(bytes.size());
    while (!bytes.empty()) {
      while (array_ < arrays_.size() && next_ == arrays_[array_].count) {
        ++array_;
        next_ = 0;
      }
      if (array_ == arrays_.size()) {
        return absl::DataLossError(
            absl::StrCat("DownloadMesh: more than the ", total_, " bytes the header announced"));
      }
      const size_t width = DataTypeSize(arrays_[array_].dtype);
      if (!partial_.empty() || bytes.size() < width) {
        const size_t take = std::min(width - partial_.size(), bytes.size());
        partial_.append(bytes.substr(0, take));
        bytes.remove_prefix(take);
        if (partial_.size() == width) {
          Store(partial_.data(), 1);
          partial_.clear();
        }
        continue;
      }
      const size_t n = std::min(arrays_[array_].count - next_, bytes.size() / width);
      Store(bytes.data(), n);
      bytes.remove_prefix(n * width);
    }
    return absl::OkStatus();
  }

  // OK once every byte the header announced has arrived.
  absl::Status Finish() const {
    if (!started_) return absl::DataLossError("DownloadMesh: the stream ended without its header");
    if (received_ != total_) {
      return absl::DataLossError(absl::StrCat("DownloadMesh: the stream ended after ", received_,
                                              " of the ", total_, " bytes the header announced"));
    }
    return absl::OkStatus();
  }

  double fraction() const { return total_ > 0 ? double(received_) / double(total_) : 1.0; }

 private:
  struct Array {
    DataType dtype;
    std::variant<double*, int64_t*> out;
    size_t count;  // values
  };

  template <class Out>
  absl::Status Add(const std::string& what, v1::DataType code,
                   std::initializer_list<DataType> allowed, Out* out, size_t count) {
    const DataType dtype = internal::FromProto(code);
    if (std::find(allowed.begin(), allowed.end(), dtype) == allowed.end()) {
      return absl::DataLossError(absl::StrCat("DownloadMesh: ", what, " of dtype ",
                                              v1::DataType_Name(code), " in the header"));
    }
    arrays_.push_back({dtype, out, count});
    total_ += int64_t(count * DataTypeSize(dtype));
    return absl::OkStatus();
  }

  // `n` values of the current array.
  void Store(const char* in, size_t n) {
    const Array& a = arrays_[array_];
    std::visit([&](auto* out) { ConvertAny(a.dtype, in, n, out + next_); }, a.out);
    next_ += n;
  }

  bool started_ = false;
  std::vector<Array> arrays_;
  size_t array_ = 0;     // being filled
  size_t next_ = 0;      // its next value
  std::string partial_;  // the first bytes of a value cut between chunks
  int64_t received_ = 0;
  int64_t total_ = 0;
};

}  // namespace

const MeshField* MeshArrays::Field(std::string_view name) const {
  auto it = std::find_if(fields.begin(), fields.end(),
                         [&](const MeshField& f) { return f.name == name; });
  return it == fields.end() ? nullptr : &*it;
}

absl::StatusOr<MeshArrays> Client::DownloadMesh(std::string_view mesh_id,
                                                const std::vector<std::string>& fields,
                                                const DownloadOptions& options) {
  if (options.all_fields && !fields.empty()) {
    return absl::InvalidArgumentError(
        "fields, options.all_fields: give the fields or all_fields, not both");
  }
  v1::DownloadMeshRequest request;
  request.set_mesh_id(std::string(mesh_id));
  request.mutable_fields()->Add(fields.begin(), fields.end());
  request.set_all_fields(options.all_fields);

  MeshArrays mesh;
  Decoder decoder;
  std::unique_ptr<grpc::ClientContext> context = core_->MeshContext();
  std::unique_ptr<grpc::ClientReader<v1::DownloadMeshResponse>> reader =
      core_->stub->DownloadMesh(context.get(), request);
  absl::Status problem;  // a malformed stream: the call is cancelled and this returned
  v1::DownloadMeshResponse response;
  try {
    while (problem.ok() && reader->Read(&response)) {
      if (response.has_header()) {
        problem = decoder.Start(response.header(), mesh);
      } else if (response.has_chunk()) {
        problem = decoder.Take(response.chunk());
        if (problem.ok() && options.progress) options.progress(decoder.fraction());
      }
    }
  } catch (...) {  // from the callback: end the call before the stack unwinds
    context->TryCancel();
    while (reader->Read(&response)) {
    }
    reader->Finish();
    throw;
  }
  if (!problem.ok()) {
    context->TryCancel();
    while (reader->Read(&response)) {
    }
  }
  const grpc::Status status = reader->Finish();
  ACTOPO_RETURN_IF_ERROR(problem);
  ACTOPO_RETURN_IF_ERROR(internal::FromGrpc(status));
  ACTOPO_RETURN_IF_ERROR(decoder.Finish());
  return mesh;
}

}  // namespace actopo::client
