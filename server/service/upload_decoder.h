// An upload's wire format, checked and decoded without a call or a server (so it can be fuzzed):
// a header with counts, dtypes, point fields and the SHA-256 of the data, then the raw
// little-endian arrays in order (points, tetrahedra, each field).
//
//   ASSIGN_OR_RETURN(const size_t bytes, CheckUploadHeader(header));  // before any chunk
//   ... receive exactly `bytes` ...
//   ASSIGN_OR_RETURN(Mesh mesh, DecodeUpload(header, data));
//
// Errors name the header field or the array and position (INVALID_ARGUMENT, OUT_OF_RANGE for a
// vertex id, DATA_LOSS for a checksum mismatch). The mesh still goes through ValidateMesh later.
#ifndef ACTOPO_SERVER_SERVICE_UPLOAD_DECODER_H_
#define ACTOPO_SERVER_SERVICE_UPLOAD_DECODER_H_

#include <cstddef>
#include <string_view>

#include "absl/status/statusor.h"
#include "actopo/v1/topology_service.pb.h"
#include "server/core/mesh.h"

namespace actopo::service {

// The number of raw bytes the header announces, or why the header is refused.
absl::StatusOr<size_t> CheckUploadHeader(const v1::UploadMeshHeader& header);

// The mesh from exactly the announced bytes, after checking their SHA-256.
absl::StatusOr<Mesh> DecodeUpload(const v1::UploadMeshHeader& header, std::string_view data);

}  // namespace actopo::service

#endif  // ACTOPO_SERVER_SERVICE_UPLOAD_DECODER_H_
