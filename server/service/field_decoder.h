// AddFields' wire format, checked and decoded as the bytes arrive (no copy of the raw data is
// kept), without a call or a server so that it can be tested and fuzzed: a header naming the
// fields (FLOAT32 or FLOAT64, one value per vertex of the mesh) and the SHA-256 of their bytes,
// then the values of each field in turn, in chunks of any size (then the SHA-256, when the header
// says it comes last).
//
//   ASSIGN_OR_RETURN(FieldDecoder decoder, FieldDecoder::Start(header, mesh_vertices));
//   for (chunk : chunks) RETURN_IF_ERROR(decoder.Append(chunk));
//   ASSIGN_OR_RETURN(std::vector<PointField> fields, decoder.Finish());
//
// Errors name the header field, or the field and vertex of a bad value: INVALID_ARGUMENT, and
// DATA_LOSS when the bytes do not hash to the announced SHA-256.
#ifndef ACTOPO_SERVER_SERVICE_FIELD_DECODER_H_
#define ACTOPO_SERVER_SERVICE_FIELD_DECODER_H_

#include <cstdint>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "absl/status/statusor.h"
#include "actopo/v1/topology_service.pb.h"
#include "server/algorithms/digest.h"
#include "server/core/mesh.h"

namespace actopo::service {

class FieldDecoder {
 public:
  static absl::StatusOr<FieldDecoder> Start(const v1::AddFieldsHeader& header, int64_t vertices);

  // Every byte the header announces.
  size_t expected_bytes() const { return expected_; }
  size_t received_bytes() const { return received_; }
  // Decodes the next bytes; refuses more than announced and non-finite values.
  absl::Status Append(std::string_view chunk);
  // The digest sent after the chunks (header.sha256_last), before Finish.
  absl::Status SetDigest(std::string_view sha256);
  // The fields, once every byte came and hashed as announced.
  absl::StatusOr<std::vector<PointField>> Finish();

 private:
  FieldDecoder() = default;
  // `count` values of the current field (little-endian, of its size, any alignment), which
  // they do not overrun.
  absl::Status Take(const char* bytes, int64_t count);

  std::vector<PointField> fields_;
  std::vector<int> sizes_;  // bytes per value of each field
  int64_t vertices_ = 0;
  size_t expected_ = 0, received_ = 0;
  size_t field_ = 0;    // the field being filled
  int64_t vertex_ = 0;  // its next vertex
  std::string carry_;   // a value split across chunks
  static absl::Status CheckDigest(std::string_view field, std::string_view digest,
                                  bool may_be_empty);

  std::string sha256_;  // announced; empty: not checked (or not come yet, with digest_last_)
  bool digest_last_ = false;
  std::unique_ptr<Sha256> hash_;
};

}  // namespace actopo::service

#endif  // ACTOPO_SERVER_SERVICE_FIELD_DECODER_H_
