// The partition: the PR-octree over arbitrary points (coincident, clustered, huge and tiny
// coordinates) and block labels from arbitrary doubles. Either gives one block per vertex,
// numbered densely from 0 with no empty block, or (labels) a clean error.
//
// Input: 1 byte of bucket capacity, then doubles (x, y, z per point; also read as labels).
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <vector>

#include "server/core/partition.h"

namespace {

void CheckDense(const std::vector<int32_t>& blocks) {
  if (blocks.empty()) return;
  std::vector<char> used(blocks.size(), 0);
  int32_t top = -1;
  for (int32_t b : blocks) {
    if (b < 0 || size_t(b) >= blocks.size()) std::abort();
    used[b] = 1;
    top = std::max(top, b);
  }
  for (int32_t b = 0; b <= top; ++b) {
    if (!used[b]) std::abort();
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size < 1) return 0;
  const int32_t capacity = 1 + data[0] % 64;
  std::vector<double> values((size - 1) / sizeof(double));
  if (!values.empty()) std::memcpy(values.data(), data + 1, values.size() * sizeof(double));
  // The server refuses non-finite points before partitioning (ValidateMesh).
  std::vector<double> points(values.begin(), values.begin() + values.size() / 3 * 3);
  for (double& c : points) {
    if (!std::isfinite(c)) c = 0;
  }
  const std::vector<int32_t> octree =
      actopo::OctreeBlocks(points, {.bucket_capacity = capacity, .max_depth = 32});
  if (octree.size() != points.size() / 3) std::abort();
  CheckDense(octree);
  const absl::StatusOr<std::vector<int32_t>> labels = actopo::LabelBlocks(values);
  if (labels.ok()) {
    if (labels->size() != values.size()) std::abort();
    CheckDense(*labels);
  }
  return 0;
}
