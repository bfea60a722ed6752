// Vertex clustering into blocks: a PR-octree over vertex positions, or a supplied label array.
//
//   std::vector<int32_t> block_of_vertex = OctreeBlocks(mesh.points, {.bucket_capacity = 1000});
//   ASSIGN_OR_RETURN(std::vector<int32_t> blocks, LabelBlocks(labels));
//
// Both return one block id per input vertex, blocks numbered 0..B-1 without gaps. The octree
// numbers leaves in depth-first order (children in Morton order: x fastest, then y, then z), so
// consecutive blocks are spatially close, which is what linear prefetching relies on.
#ifndef ACTOPO_SERVER_CORE_PARTITION_H_
#define ACTOPO_SERVER_CORE_PARTITION_H_

#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "server/core/mesh.h"

namespace actopo {

struct OctreeOptions {
  // Maximum vertices per leaf; a leaf holding more is split into 8.
  int32_t bucket_capacity = 1000;
  // Splitting stops at this depth even above capacity (only coincident or extremely clustered
  // points get there), so duplicate points cannot recurse forever.
  int max_depth = 32;
};

// points: x, y, z per vertex. Returns the block of each vertex.
std::vector<int32_t> OctreeBlocks(std::span<const double> points, const OctreeOptions& options);

// Blocks from a per-vertex label array (any integers; e.g. a "BlockLabel" point field). Labels
// are renumbered densely in ascending label order. Fails on non-integral or out-of-int32 labels.
absl::StatusOr<std::vector<int32_t>> LabelBlocks(std::span<const double> labels);

// How a mesh is split into blocks: by the octree, or by a block-label point field when named.
struct PartitionOptions {
  int32_t bucket_capacity = 1000;
  std::string block_label_field;  // empty: octree
};

// The block of each input vertex for `mesh` under `options`.
absl::StatusOr<std::vector<int32_t>> ComputeBlocks(const Mesh& mesh,
                                                   const PartitionOptions& options);

}  // namespace actopo

#endif  // ACTOPO_SERVER_CORE_PARTITION_H_
