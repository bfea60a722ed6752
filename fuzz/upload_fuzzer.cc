// The upload wire format: a header (protobuf bytes) and raw arrays, through the header checks and
// the decoder; a mesh that passes validation then goes through the octree, the static encoding
// and a whole explicit structure, so arbitrary small tetrahedral meshes reach the core.
//
// Input: 2 bytes of header length (little-endian), 1 byte of options (bit 0: keep the header's
// own checksum instead of the data's; the rest picks the block size), the header, the data.
#include <cstdint>
#include <cstdlib>
#include <string_view>

#include "server/algorithms/digest.h"
#include "server/core/explicit_structure.h"
#include "server/core/partition.h"
#include "server/core/topology.h"
#include "server/service/upload_decoder.h"

namespace {

using actopo::v1::UploadMeshHeader;

constexpr size_t kMaxBytes = 1 << 16;  // small meshes: many runs per second

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size < 3) return 0;
  const size_t header_size = std::min<size_t>(size_t(data[0]) | size_t(data[1]) << 8, size - 3);
  const uint8_t options = data[2];
  UploadMeshHeader header;
  if (!header.ParseFromArray(data + 3, int(header_size))) return 0;
  const std::string_view body(reinterpret_cast<const char*>(data) + 3 + header_size,
                              size - 3 - header_size);
  const absl::StatusOr<size_t> bytes = actopo::service::CheckUploadHeader(header);
  if (!bytes.ok() || *bytes > kMaxBytes) return 0;
  if ((options & 1) == 0) header.set_sha256(actopo::Sha256Hex(body));
  absl::StatusOr<actopo::Mesh> mesh = actopo::service::DecodeUpload(header, body);
  if (!mesh.ok() || !actopo::ValidateMesh(*mesh).ok()) return 0;
  const std::vector<int32_t> blocks =
      actopo::OctreeBlocks(mesh->points, {.bucket_capacity = 1 + (options >> 1) % 16});
  if (blocks.size() != size_t(mesh->num_vertices())) std::abort();
  auto topology = actopo::Topology::Build(*mesh, blocks, {.threads = 1});
  if (!topology.ok()) return 0;
  auto structure = actopo::ExplicitStructure::Build(*topology, {.threads = 1});
  if (!structure.ok()) std::abort();  // a valid mesh always has every relation
  return 0;
}
