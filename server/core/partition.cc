#include "server/core/partition.h"

#include <algorithm>
#include <cmath>
#include <numeric>

#include "absl/strings/str_cat.h"
#include "server/core/parallel.h"

namespace actopo {
namespace {

struct OctreeBuilder {
  // A node of the tree: a range of `order` and its cell.
  struct Node {
    int64_t begin, end;
    std::array<double, 3> lo, hi;
    int depth;
  };

  std::span<const double> points;
  OctreeOptions options;
  std::vector<int32_t> order;  // vertex ids, permuted so each node is a contiguous range
  std::vector<int32_t> block;  // result, by vertex id

  bool IsLeaf(const Node& node) const {
    return node.end - node.begin <= options.bucket_capacity || node.depth >= options.max_depth;
  }

  // Partitions a node's range among its 8 children and calls child(node) for each, in Morton
  // order (z slowest).
  template <class Child>
  void SplitNode(const Node& node, Child&& child) {
    std::array<double, 3> mid;
    for (int k = 0; k < 3; ++k) mid[k] = 0.5 * (node.lo[k] + node.hi[k]);
    // Three nested binary partitions give the 8 children.
    auto below = [&](int axis) {
      return [&, axis](int32_t v) { return points[3 * size_t(v) + axis] < mid[axis]; };
    };
    int32_t* base = order.data();
    std::array<int64_t, 9> cut;
    cut[0] = node.begin;
    cut[8] = node.end;
    cut[4] = std::partition(base + node.begin, base + node.end, below(2)) - base;
    for (int hz = 0; hz < 2; ++hz) {
      const int64_t b = cut[4 * hz], e = cut[4 * hz + 4];
      cut[4 * hz + 2] = std::partition(base + b, base + e, below(1)) - base;
      for (int hy = 0; hy < 2; ++hy) {
        const int64_t b2 = cut[4 * hz + 2 * hy], e2 = cut[4 * hz + 2 * hy + 2];
        cut[4 * hz + 2 * hy + 1] = std::partition(base + b2, base + e2, below(0)) - base;
      }
    }
    for (int c = 0; c < 8; ++c) {
      Node sub{cut[c], cut[c + 1], node.lo, node.hi, node.depth + 1};
      for (int k = 0; k < 3; ++k) (c >> k & 1 ? sub.lo[k] : sub.hi[k]) = mid[k];
      child(sub);
    }
  }

  // Numbers the leaves under `node` from next_block on, depth first.
  void Split(const Node& node, int32_t& next_block) {
    if (node.begin == node.end) return;
    if (IsLeaf(node)) {
      for (int64_t i = node.begin; i < node.end; ++i) block[order[i]] = next_block;
      ++next_block;
      return;
    }
    SplitNode(node, [&](const Node& child) { Split(child, next_block); });
  }

  // The nodes under `node` of at most `size` vertices (or leaves) whose parents are larger, in
  // depth-first order: subtrees to number independently.
  void Subtrees(const Node& node, int64_t size, std::vector<Node>& out) {
    if (node.begin == node.end) return;
    if (node.end - node.begin <= size || IsLeaf(node)) {
      out.push_back(node);
      return;
    }
    SplitNode(node, [&](const Node& child) { Subtrees(child, size, out); });
  }
};

}  // namespace

std::vector<int32_t> OctreeBlocks(std::span<const double> points, const OctreeOptions& options) {
  const int64_t n = static_cast<int64_t>(points.size() / 3);
  OctreeBuilder builder{points, options, std::vector<int32_t>(n), std::vector<int32_t>(n, 0)};
  builder.options.bucket_capacity = std::max(builder.options.bucket_capacity, 1);
  std::iota(builder.order.begin(), builder.order.end(), 0);
  if (n == 0) return {};
  std::array<double, 3> lo, hi;
  for (int k = 0; k < 3; ++k) {
    lo[k] = hi[k] = points[k];
  }
  for (int64_t v = 0; v < n; ++v) {
    for (int k = 0; k < 3; ++k) {
      lo[k] = std::min(lo[k], points[3 * v + k]);
      hi[k] = std::max(hi[k], points[3 * v + k]);
    }
  }
  // A cube around the bounding box keeps octants cubic, as a PR-octree's cells are.
  double side = 0;
  for (int k = 0; k < 3; ++k) side = std::max(side, hi[k] - lo[k]);
  for (int k = 0; k < 3; ++k) hi[k] = lo[k] + side;
  // Points exactly on the upper faces fall in the upper child ("<" split), which is fine: the
  // split only needs to be deterministic.
  // The top levels are split on this thread down to subtrees of at most n / 64 vertices; those
  // are split in parallel, each numbering its blocks from 0, then shifted past the blocks of the
  // subtrees before it: the same blocks, in the same order, as one depth-first pass.
  std::vector<OctreeBuilder::Node> subtrees;
  builder.Subtrees({0, n, lo, hi, 0}, std::max<int64_t>(n / 64, 1), subtrees);
  std::vector<int32_t> first(subtrees.size() + 1, 0);
  ParallelFor(int64_t(subtrees.size()), DefaultThreads(), [&](int64_t i, int) {
    builder.Split(subtrees[i], first[i + 1]);  // its block count
  });
  for (size_t i = 0; i < subtrees.size(); ++i) first[i + 1] += first[i];
  ParallelFor(int64_t(subtrees.size()), DefaultThreads(), [&](int64_t i, int) {
    for (int64_t k = subtrees[i].begin; k < subtrees[i].end; ++k) {
      builder.block[builder.order[k]] += first[i];
    }
  });
  return std::move(builder.block);
}

absl::StatusOr<std::vector<int32_t>> LabelBlocks(std::span<const double> labels) {
  std::vector<int64_t> as_int(labels.size());
  for (size_t v = 0; v < labels.size(); ++v) {
    const double l = labels[v];
    if (!std::isfinite(l) || l != std::floor(l) || l < INT32_MIN || l > INT32_MAX) {
      return absl::InvalidArgumentError(
          absl::StrCat("block labels: vertex ", v, " has label ", l, ", not a 32-bit integer"));
    }
    as_int[v] = static_cast<int64_t>(l);
  }
  std::vector<int64_t> distinct = as_int;
  std::sort(distinct.begin(), distinct.end());
  distinct.erase(std::unique(distinct.begin(), distinct.end()), distinct.end());
  std::vector<int32_t> block(labels.size());
  for (size_t v = 0; v < labels.size(); ++v) {
    block[v] = static_cast<int32_t>(std::lower_bound(distinct.begin(), distinct.end(), as_int[v]) -
                                    distinct.begin());
  }
  return block;
}

absl::StatusOr<std::vector<int32_t>> ComputeBlocks(const Mesh& mesh,
                                                   const PartitionOptions& options) {
  if (options.block_label_field.empty()) {
    if (options.bucket_capacity < 1) {
      return absl::InvalidArgumentError(
          absl::StrCat("block size: ", options.bucket_capacity, " must be at least 1"));
    }
    return OctreeBlocks(mesh.points, {.bucket_capacity = options.bucket_capacity});
  }
  const PointField* labels = mesh.FindField(options.block_label_field);
  if (labels == nullptr) {
    return absl::NotFoundError(
        absl::StrCat("block labels: point field '", options.block_label_field, "' not found"));
  }
  return LabelBlocks(labels->values);
}

}  // namespace actopo
