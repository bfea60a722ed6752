#include "server/results/vertex_boundary.h"

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

int32_t VertexBoundary::blocks_computed() const {
  MutexLock lock(mu_);
  return computed_;
}

}  // namespace actopo
