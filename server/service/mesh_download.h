// DownloadMesh's bytes: a loaded mesh in the upload's own format (UploadMeshHeader, then the
// points, the tetrahedra and the fields asked for, concatenated), made chunk by chunk from what
// the server keeps, so that no copy of the whole mesh is ever made for a download.
//
//   ASSIGN_OR_RETURN(MeshDownload download, MeshDownload::Start(mesh, request));
//   send(download.header());
//   std::string chunk;
//   while (download.Next(kChunkBytes, &chunk)) send(chunk);
//
// The points are the input points; each tetrahedron is the input one, its vertices in the order
// they were given (the topology keeps them sorted, and LoadedMesh::input_corners says where each
// came from), as INT32 when every vertex id fits, else INT64; a field keeps the dtype it was
// loaded or added with, unless its values do not fit it (an unsigned integer array: the next
// wider type that holds them). Errors: NOT_FOUND for an unknown field, INVALID_ARGUMENT for a field
// named twice or fields together with all_fields.
#ifndef ACTOPO_SERVER_SERVICE_MESH_DOWNLOAD_H_
#define ACTOPO_SERVER_SERVICE_MESH_DOWNLOAD_H_

#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "actopo/v1/topology_service.pb.h"
#include "server/service/field_set.h"
#include "server/service/mesh_registry.h"

namespace actopo::service {

class MeshDownload {
 public:
  static absl::StatusOr<MeshDownload> Start(std::shared_ptr<const LoadedMesh> mesh,
                                            const v1::DownloadMeshRequest& request);

  const v1::UploadMeshHeader& header() const { return header_; }
  // Every byte the header announces.
  int64_t total_bytes() const;
  // The next bytes, whole values of one array, about `max_bytes` of them (at least one value);
  // false once everything was given.
  bool Next(size_t max_bytes, std::string* chunk);

 private:
  MeshDownload() = default;
  // Array k: 0 the points, 1 the tetrahedra, 2 + i field i. Its values' count and size.
  int64_t count(size_t array) const;
  int value_bytes(size_t array) const;
  void WriteTetrahedra(int64_t first, int64_t count, char* out) const;
  void WriteField(const PointField& field, v1::DataType dtype, int64_t first, int64_t count,
                  char* out) const;
  static v1::DataType DtypeOf(const PointField& field);

  std::shared_ptr<const LoadedMesh> mesh_;
  std::vector<FieldSet::Ref> fields_;
  v1::UploadMeshHeader header_;
  bool wide_ids_ = false;  // INT64 tetrahedra
  size_t array_ = 0;       // being sent
  int64_t next_ = 0;       // its next value
};

}  // namespace actopo::service

#endif  // ACTOPO_SERVER_SERVICE_MESH_DOWNLOAD_H_
