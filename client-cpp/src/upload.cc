// Client::UploadMesh and Client::AddFields: shapes checked here, then a header with the SHA-256
// of the data and the raw little-endian bytes (points, tetrahedra, fields; or the added fields'
// values) in chunks that may straddle arrays, read from the caller's spans as they go.
#include <algorithm>
#include <cmath>
#include <set>
#include <variant>

#include "absl/strings/str_cat.h"
#include "actopo/client.h"
#include "src/internal/convert.h"
#include "src/internal/core.h"
#include "src/internal/names.h"
#include "src/internal/sha256.h"

namespace actopo::client {
namespace {

constexpr int64_t kMaxCount = 2147483647;  // the server's ids are 32-bit

absl::Status CheckShapes(size_t points, size_t tetrahedra, const std::vector<ScalarField>& fields,
                         size_t chunk_bytes) {
  if (points == 0 || points % 3 != 0) {
    return absl::InvalidArgumentError(absl::StrCat(
        "points: ", points, " values; expected 3 per vertex (x, y, z) and at least one vertex"));
  }
  if (tetrahedra == 0 || tetrahedra % 4 != 0) {
    return absl::InvalidArgumentError(absl::StrCat(
        "tetrahedra: ", tetrahedra,
        " values; expected 4 vertex ids per tetrahedron and at least one tetrahedron"));
  }
  if (points / 3 > kMaxCount || tetrahedra / 4 > kMaxCount) {
    return absl::InvalidArgumentError("points, tetrahedra: more than 2^31 - 1 elements");
  }
  std::set<std::string> names;
  for (size_t i = 0; i < fields.size(); ++i) {
    const ScalarField& f = fields[i];
    if (f.name.empty()) {
      return absl::InvalidArgumentError(absl::StrCat("fields[", i, "].name: empty"));
    }
    if (!names.insert(f.name).second) {
      return absl::InvalidArgumentError(
          absl::StrCat("fields[", i, "].name: '", f.name, "' appears twice"));
    }
    if (f.values.size() != points / 3) {
      return absl::InvalidArgumentError(
          absl::StrCat("fields[", i, "] '", f.name, "': ", f.values.size(), " values for ",
                       points / 3, " vertices; expected one per vertex"));
    }
  }
  if (chunk_bytes == 0) {
    return absl::InvalidArgumentError("options.chunk_bytes: 0; expected a positive size");
  }
  return absl::OkStatus();
}

// Sends the concatenation of `buffers` as chunks of exactly `chunk_bytes` (the last may be
// shorter), in Request's `chunk`. Returns false when the stream broke (Finish then says why).
template <class Request>
bool WriteChunks(const std::vector<std::span<const std::byte>>& buffers, size_t chunk_bytes,
                 grpc::ClientWriter<Request>& writer) {
  Request message;
  std::string* chunk = message.mutable_chunk();
  chunk->reserve(chunk_bytes);
  for (std::span<const std::byte> buffer : buffers) {
    while (!buffer.empty()) {
      const size_t take = std::min(buffer.size(), chunk_bytes - chunk->size());
      chunk->append(reinterpret_cast<const char*>(buffer.data()), take);
      buffer = buffer.subspan(take);
      if (chunk->size() == chunk_bytes) {
        if (!writer.Write(message)) return false;
        chunk->clear();
      }
    }
  }
  return chunk->empty() || writer.Write(message);
}

// The SHA-256 of the concatenation of `buffers`, read once in place.
absl::StatusOr<std::string> Digest(const std::vector<std::span<const std::byte>>& buffers) {
  internal::Sha256 sha;
  for (std::span<const std::byte> b : buffers) sha.Update(b);
  return sha.HexDigest();
}

template <class Index>
absl::StatusOr<MeshInfo> Upload(internal::Core& core, std::span<const double> points,
                                std::span<const Index> tetrahedra,
                                const std::vector<ScalarField>& fields,
                                const UploadOptions& options) {
  ACTOPO_RETURN_IF_ERROR(
      CheckShapes(points.size(), tetrahedra.size(), fields, options.chunk_bytes));
  std::vector<std::span<const std::byte>> buffers = {std::as_bytes(points),
                                                     std::as_bytes(tetrahedra)};
  for (const ScalarField& f : fields) buffers.push_back(std::as_bytes(f.values));

  v1::UploadMeshRequest first;
  v1::UploadMeshHeader* header = first.mutable_header();
  header->set_name(options.name);
  header->set_num_vertices(int64_t(points.size() / 3));
  header->set_num_tetrahedra(int64_t(tetrahedra.size() / 4));
  header->set_points_dtype(v1::DATA_TYPE_FLOAT64);
  header->set_tetrahedra_dtype(internal::ToProto(kDataTypeOf<Index>));
  for (const ScalarField& f : fields) {
    v1::UploadField* field = header->add_fields();
    field->set_name(f.name);
    field->set_dtype(v1::DATA_TYPE_FLOAT64);
  }
  ACTOPO_ASSIGN_OR_RETURN(*header->mutable_sha256(), Digest(buffers));
  *header->mutable_partition() = internal::ToProto(options.partition);

  v1::UploadMeshResponse response;
  std::unique_ptr<grpc::ClientContext> context = core.MeshContext();
  std::unique_ptr<grpc::ClientWriter<v1::UploadMeshRequest>> writer =
      core.stub->UploadMesh(context.get(), &response);
  // A failed write means the server already ended the call: Finish gives its status.
  if (writer->Write(first) && WriteChunks(buffers, options.chunk_bytes, *writer)) {
    writer->WritesDone();
  }
  ACTOPO_RETURN_IF_ERROR(internal::FromGrpc(writer->Finish()));
  return internal::FromProto(response.mesh());
}

size_t Count(const FieldValues& field) {
  return std::visit([](auto values) { return values.size(); }, field.values);
}

std::span<const std::byte> Bytes(const FieldValues& field) {
  return std::visit([](auto values) { return std::as_bytes(values); }, field.values);
}

v1::DataType DtypeOf(const FieldValues& field) {
  return std::holds_alternative<std::span<const float>>(field.values) ? v1::DATA_TYPE_FLOAT32
                                                                      : v1::DATA_TYPE_FLOAT64;
}

// What the client can see wrong in AddFields' input; the server checks the rest (the count
// against the mesh's vertices, names it has, finite values).
absl::Status CheckFields(const std::vector<FieldValues>& fields, const AddFieldsOptions& options) {
  if (fields.empty()) {
    return absl::InvalidArgumentError("fields: none given; expected at least one field");
  }
  std::set<std::string> names;
  for (size_t i = 0; i < fields.size(); ++i) {
    const FieldValues& f = fields[i];
    if (f.name.empty()) {
      return absl::InvalidArgumentError(absl::StrCat("fields[", i, "].name: empty"));
    }
    if (!names.insert(f.name).second) {
      return absl::InvalidArgumentError(
          absl::StrCat("fields[", i, "].name: '", f.name, "' appears twice"));
    }
    // The values travel concatenated, so fields of different lengths would shift into each
    // other unseen if their total matched the server's expectation.
    if (Count(f) == 0 || Count(f) != Count(fields[0])) {
      return absl::InvalidArgumentError(absl::StrCat(
          "fields[", i, "] '", f.name, "': ", Count(f), " values",
          i == 0 ? ""
                 : absl::StrCat(" but fields[0] '", fields[0].name, "' has ", Count(fields[0])),
          "; expected one per vertex of the mesh"));
    }
    if (f.time && !std::isfinite(*f.time)) {
      return absl::InvalidArgumentError(
          absl::StrCat("fields[", i, "] '", f.name, "': time ", *f.time, " is not finite"));
    }
  }
  if (options.chunk_bytes == 0) {
    return absl::InvalidArgumentError("options.chunk_bytes: 0; expected a positive size");
  }
  if (options.sha256 && !options.sha256->empty()) {
    const std::string& hex = *options.sha256;
    const bool digits = std::all_of(hex.begin(), hex.end(), [](char c) {
      return (c >= '0' && c <= '9') || (c >= 'a' && c <= 'f');
    });
    if (hex.size() != 64 || !digits) {
      return absl::InvalidArgumentError(
          absl::StrCat("options.sha256: '", hex,
                       "' is not 64 lowercase hex digits (a SHA-256), nor empty (no check)"));
    }
  }
  return absl::OkStatus();
}

}  // namespace

absl::StatusOr<MeshInfo> Client::AddFields(std::string_view mesh_id,
                                           const std::vector<FieldValues>& fields,
                                           const AddFieldsOptions& options) {
  ACTOPO_RETURN_IF_ERROR(CheckFields(fields, options));
  std::vector<std::span<const std::byte>> buffers;
  for (const FieldValues& f : fields) buffers.push_back(Bytes(f));

  v1::AddFieldsRequest first;
  v1::AddFieldsHeader* header = first.mutable_header();
  header->set_mesh_id(std::string(mesh_id));
  for (const FieldValues& f : fields) {
    v1::UploadField* field = header->add_fields();
    field->set_name(f.name);
    field->set_dtype(DtypeOf(f));
    if (f.time) field->set_time(*f.time);
  }
  if (options.sha256) {
    header->set_sha256(*options.sha256);
  } else {
    ACTOPO_ASSIGN_OR_RETURN(*header->mutable_sha256(), Digest(buffers));
  }

  v1::AddFieldsResponse response;
  std::unique_ptr<grpc::ClientContext> context = core_->MeshContext();
  std::unique_ptr<grpc::ClientWriter<v1::AddFieldsRequest>> writer =
      core_->stub->AddFields(context.get(), &response);
  // A failed write means the server already ended the call: Finish gives its status.
  if (writer->Write(first) && WriteChunks(buffers, options.chunk_bytes, *writer)) {
    writer->WritesDone();
  }
  ACTOPO_RETURN_IF_ERROR(internal::FromGrpc(writer->Finish()));
  return internal::FromProto(response.mesh());
}

absl::StatusOr<MeshInfo> Client::AddField(std::string_view mesh_id, const FieldValues& field,
                                          const AddFieldsOptions& options) {
  return AddFields(mesh_id, {field}, options);
}

absl::StatusOr<MeshInfo> Client::UploadMesh(std::span<const double> points,
                                            std::span<const int32_t> tetrahedra,
                                            const std::vector<ScalarField>& fields,
                                            const UploadOptions& options) {
  return Upload(*core_, points, tetrahedra, fields, options);
}

absl::StatusOr<MeshInfo> Client::UploadMesh(std::span<const double> points,
                                            std::span<const int64_t> tetrahedra,
                                            const std::vector<ScalarField>& fields,
                                            const UploadOptions& options) {
  return Upload(*core_, points, tetrahedra, fields, options);
}

}  // namespace actopo::client
