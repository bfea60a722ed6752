#include "server/service/field_decoder.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <set>

#include "absl/strings/str_cat.h"
#include "server/core/status_macros.h"

namespace actopo::service {

absl::StatusOr<FieldDecoder> FieldDecoder::Start(const v1::AddFieldsHeader& header,
                                                 int64_t vertices) {
  if (header.fields_size() == 0) {
    return absl::InvalidArgumentError("header.fields: no field announced");
  }
  RETURN_IF_ERROR(CheckDigest("header.sha256", header.sha256(), /*may_be_empty=*/true));
  if (header.sha256_last() && !header.sha256().empty()) {
    return absl::InvalidArgumentError(
        "header.sha256: given, with sha256_last also set; send the digest once");
  }
  FieldDecoder d;
  d.vertices_ = vertices;
  d.sha256_ = header.sha256();
  d.digest_last_ = header.sha256_last();
  if (!d.sha256_.empty() || d.digest_last_) d.hash_ = std::make_unique<Sha256>();
  std::set<std::string> names;
  for (int i = 0; i < header.fields_size(); ++i) {
    const v1::UploadField& f = header.fields(i);
    if (f.name().empty()) {
      return absl::InvalidArgumentError(absl::StrCat("header.fields[", i, "].name: empty"));
    }
    if (!names.insert(f.name()).second) {
      return absl::InvalidArgumentError(
          absl::StrCat("header.fields[", i, "].name: '", f.name(), "' is announced twice"));
    }
    if (f.dtype() != v1::DATA_TYPE_FLOAT32 && f.dtype() != v1::DATA_TYPE_FLOAT64) {
      const std::string name = v1::DataType_Name(f.dtype());
      return absl::InvalidArgumentError(absl::StrCat(
          "header.fields[", i, "].dtype: ", name.empty() ? std::to_string(int(f.dtype())) : name,
          " is not FLOAT32 or FLOAT64 (a scalar field to analyse)"));
    }
    if (f.has_time() && !std::isfinite(f.time())) {
      return absl::InvalidArgumentError(
          absl::StrCat("header.fields[", i, "].time: ", f.time(), " is not finite"));
    }
    const int size = f.dtype() == v1::DATA_TYPE_FLOAT32 ? 4 : 8;
    d.sizes_.push_back(size);
    d.fields_.push_back({.name = f.name(), .source_bytes = int8_t(size)});
    d.expected_ += size_t(vertices) * size;
  }
  d.fields_[0].values.reserve(size_t(vertices));
  return d;
}

absl::Status FieldDecoder::Take(const char* bytes, int64_t count) {
  PointField& field = fields_[field_];
  const size_t start = field.values.size();
  field.values.resize(start + size_t(count));
  double* out = field.values.data() + start;
  if (sizes_[field_] == 8) {
    std::memcpy(out, bytes, size_t(count) * 8);
  } else {
    for (int64_t i = 0; i < count; ++i) {
      float f;
      std::memcpy(&f, bytes + 4 * i, 4);
      out[i] = f;
    }
  }
  bool finite = true;
  for (int64_t i = 0; i < count; ++i) finite &= std::isfinite(out[i]);
  if (!finite) {
    const int64_t bad =
        std::find_if(out, out + count, [](double v) { return !std::isfinite(v); }) - out;
    return absl::InvalidArgumentError(
        absl::StrCat("fields[", field_, "] '", field.name, "': vertex ", vertex_ + bad,
                     " has value ", out[bad], "; a scalar field needs finite values"));
  }
  if ((vertex_ += count) == vertices_ && ++field_ < fields_.size()) {
    vertex_ = 0;
    fields_[field_].values.reserve(size_t(vertices_));
  }
  return absl::OkStatus();
}

absl::Status FieldDecoder::Append(std::string_view chunk) {
  if (digest_last_ && !sha256_.empty()) {
    return absl::InvalidArgumentError("chunk: after the sha256, which ends the values");
  }
  if (received_ + chunk.size() > expected_) {
    return absl::InvalidArgumentError(absl::StrCat(
        "chunk: received more than the ", expected_, " bytes the header announced (",
        fields_.size(), " field(s) of ", vertices_, " values: one per vertex of the mesh)"));
  }
  received_ += chunk.size();
  if (hash_) hash_->Update(chunk);
  // A value begun in the last chunk first.
  while (!carry_.empty() && !chunk.empty()) {
    const size_t need = size_t(sizes_[field_]) - carry_.size();
    const size_t take = std::min(need, chunk.size());
    carry_.append(chunk.substr(0, take));
    chunk.remove_prefix(take);
    if (carry_.size() == size_t(sizes_[field_])) {
      const std::string value = std::move(carry_);
      carry_.clear();
      if (absl::Status s = Take(value.data(), 1); !s.ok()) return s;
    }
  }
  // Then every whole value, the current field's at once.
  while (field_ < fields_.size() && chunk.size() >= size_t(sizes_[field_])) {
    const size_t size = size_t(sizes_[field_]);
    const int64_t count = std::min(int64_t(chunk.size() / size), vertices_ - vertex_);
    if (absl::Status s = Take(chunk.data(), count); !s.ok()) return s;
    chunk.remove_prefix(size_t(count) * size);
  }
  carry_.append(chunk);
  return absl::OkStatus();
}

absl::Status FieldDecoder::CheckDigest(std::string_view field, std::string_view digest,
                                       bool may_be_empty) {
  if ((may_be_empty && digest.empty()) ||
      (digest.size() == 64 && std::all_of(digest.begin(), digest.end(), [](char c) {
         return (c >= '0' && c <= '9') || (c >= 'a' && c <= 'f');
       }))) {
    return absl::OkStatus();
  }
  return absl::InvalidArgumentError(absl::StrCat(
      std::string(field), ": expected 64 lowercase hex digits (SHA-256 of the values' bytes)",
      may_be_empty ? ", or nothing" : ""));
}

absl::Status FieldDecoder::SetDigest(std::string_view sha256) {
  if (!digest_last_) {
    return absl::InvalidArgumentError(
        "sha256: a digest after the chunks needs header.sha256_last (and no header.sha256)");
  }
  if (!sha256_.empty()) return absl::InvalidArgumentError("sha256: sent twice");
  RETURN_IF_ERROR(CheckDigest("sha256", sha256, /*may_be_empty=*/false));
  sha256_ = std::string(sha256);
  return absl::OkStatus();
}

absl::StatusOr<std::vector<PointField>> FieldDecoder::Finish() {
  if (received_ != expected_) {
    return absl::InvalidArgumentError(absl::StrCat(
        "chunk: the stream ended after ", received_, " of the ", expected_,
        " bytes the header announced, in fields[", field_, "] '", fields_[field_].name, "' after ",
        vertex_, " of its ", vertices_, " values (one per vertex of the mesh)"));
  }
  if (digest_last_ && sha256_.empty()) {
    return absl::InvalidArgumentError(
        "sha256: the header announced it after the chunks (sha256_last); none came");
  }
  if (hash_) {
    const std::string digest = hash_->HexDigest();
    hash_.reset();
    if (digest != sha256_) {
      return absl::DataLossError(absl::StrCat(digest_last_ ? "sha256" : "header.sha256",
                                              ": the values hash to ", digest, ", not ", sha256_,
                                              " (corrupted in transit)"));
    }
  }
  return std::move(fields_);
}

}  // namespace actopo::service
