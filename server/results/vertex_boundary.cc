#include "server/results/vertex_boundary.h"

#include <algorithm>

#include "server/core/parallel.h"

namespace actopo {

VertexBoundary::VertexBoundary(const Topology& topology)
    : topology_(topology), blocks_(size_t(topology.num_blocks())) {}

bool VertexBoundary::operator()(SimplexId v) const {
  const int32_t b = topology_.vertex_block(v);
  MutexLock lock(mu_);
  std::vector<uint8_t>& flags = blocks_[b];
  if (flags.empty()) {  // b holds v: its row is not empty once computed
    RelationBlock vb = ComputeBlockRelation(topology_, Relation::kVB, b, scratch_);
    flags.assign(vb.values.begin(), vb.values.end());
    ++computed_;
  }
  return flags[v - topology_.block_vertex_begin(b)] != 0;
}

void VertexBoundary::Prepare(std::span<const SimplexId> vertices, int threads) const {
  std::vector<int32_t> missing;
  {
    MutexLock lock(mu_);
    std::vector<bool> listed(blocks_.size(), false);
    for (SimplexId v : vertices) {
      const int32_t b = topology_.vertex_block(v);
      if (blocks_[b].empty() && !listed[b]) {
        listed[b] = true;
        missing.push_back(b);
      }
    }
  }
  // Computed outside the lock, each thread with its own scratch; a block another caller
  // computed meanwhile is the same either way.
  std::vector<std::vector<uint8_t>> computed(missing.size());
  std::vector<BlockScratch> scratch(size_t(std::max(threads, 1)));
  ParallelFor(int64_t(missing.size()), threads, [&](int64_t i, int thread) {
    const RelationBlock vb =
        ComputeBlockRelation(topology_, Relation::kVB, missing[i], scratch[thread]);
    computed[i].assign(vb.values.begin(), vb.values.end());
  });
  MutexLock lock(mu_);
  for (size_t i = 0; i < missing.size(); ++i) {
    if (blocks_[missing[i]].empty()) {
      blocks_[missing[i]] = std::move(computed[i]);
      ++computed_;
    }
  }
}

int32_t VertexBoundary::blocks_computed() const {
  MutexLock lock(mu_);
  return computed_;
}

}  // namespace actopo
