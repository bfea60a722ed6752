#include "server/service/field_decoder.h"

#include <cmath>
#include <cstring>
#include <set>

#include "absl/strings/str_cat.h"

namespace actopo::service {

absl::StatusOr<FieldDecoder> FieldDecoder::Start(const v1::AddFieldsHeader& header,
                                                 int64_t vertices) {
  if (header.fields_size() == 0) {
    return absl::InvalidArgumentError("header.fields: no field announced");
  }
  if (!header.sha256().empty() && header.sha256().size() != 64) {
    return absl::InvalidArgumentError(
        "header.sha256: expected 64 lowercase hex digits (SHA-256 of the values' bytes), or "
        "nothing");
  }
  FieldDecoder d;
  d.vertices_ = vertices;
  d.sha256_ = header.sha256();
  if (!d.sha256_.empty()) d.hash_ = std::make_unique<Sha256>();
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

absl::Status FieldDecoder::Take(const char* p) {
  PointField& field = fields_[field_];
  double value;
  if (sizes_[field_] == 4) {
    float f;
    std::memcpy(&f, p, 4);
    value = f;
  } else {
    std::memcpy(&value, p, 8);
  }
  if (!std::isfinite(value)) {
    return absl::InvalidArgumentError(absl::StrCat("fields[", field_, "] '", field.name,
                                                   "': vertex ", vertex_, " has value ", value,
                                                   "; a scalar field needs finite values"));
  }
  field.values.push_back(value);
  if (++vertex_ == vertices_ && ++field_ < fields_.size()) {
    vertex_ = 0;
    fields_[field_].values.reserve(size_t(vertices_));
  }
  return absl::OkStatus();
}

absl::Status FieldDecoder::Append(std::string_view chunk) {
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
      if (absl::Status s = Take(value.data()); !s.ok()) return s;
    }
  }
  while (field_ < fields_.size() && chunk.size() >= size_t(sizes_[field_])) {
    const size_t size = size_t(sizes_[field_]);
    if (absl::Status s = Take(chunk.data()); !s.ok()) return s;
    chunk.remove_prefix(size);
  }
  carry_.append(chunk);
  return absl::OkStatus();
}

absl::StatusOr<std::vector<PointField>> FieldDecoder::Finish() {
  if (received_ != expected_) {
    return absl::InvalidArgumentError(absl::StrCat(
        "chunk: the stream ended after ", received_, " of the ", expected_,
        " bytes the header announced, in fields[", field_, "] '", fields_[field_].name, "' after ",
        vertex_, " of its ", vertices_, " values (one per vertex of the mesh)"));
  }
  if (hash_) {
    const std::string digest = hash_->HexDigest();
    hash_.reset();
    if (digest != sha256_) {
      return absl::DataLossError(absl::StrCat("header.sha256: the values hash to ", digest,
                                              ", not ", sha256_, " (corrupted in transit)"));
    }
  }
  return std::move(fields_);
}

}  // namespace actopo::service
