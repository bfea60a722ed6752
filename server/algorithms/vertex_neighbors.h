// Every vertex's neighbours (the VV relation, in its canonical ascending order), kept by block
// outside any structure, for passes that come back to the same vertices in no order in space
// (the simplification's removals) on structures that would compute those blocks again and again.
//
// Filled block by block while another pass holds the block's VE, any number of threads at once
// (each block by one): a vertex's neighbours are the other ends of its edges, in the same order.
// VE ascends by edge id, and edge ids follow (lowest, upper) vertex, so the edges (u, v) with u
// below v come first, ascending u, then the edges (v, w), ascending w.
//
//   VertexNeighbors kept(topology);
//   kept.FillBlock(b, reader);                     // on the thread that reads block b
//   for (SimplexId u : kept.vertex_neighbors(v)) ...
#ifndef ACTOPO_SERVER_ALGORITHMS_VERTEX_NEIGHBORS_H_
#define ACTOPO_SERVER_ALGORITHMS_VERTEX_NEIGHBORS_H_

#include <cstdint>
#include <span>
#include <vector>

#include "server/core/topology.h"

namespace actopo {

class VertexNeighbors {
 public:
  explicit VertexNeighbors(const Topology& topology)
      : topo_(&topology), rows_(topology.num_blocks()), begin_(topology.num_vertices()) {}

  const Topology& topology() const { return *topo_; }

  // Keeps the rows of block b's vertices, read through `reader` (any structure's).
  template <class Reader>
  void FillBlock(int32_t b, Reader& reader) {
    const SimplexId first = topo_->block_vertex_begin(b), last = topo_->block_vertex_begin(b + 1);
    size_t size = 0;
    for (SimplexId v = first; v < last; ++v) size += reader.vertex_edges(v).size();
    std::vector<SimplexId>& rows = rows_[b];
    rows.clear();
    rows.reserve(size);
    for (SimplexId v = first; v < last; ++v) {
      begin_[v] = uint32_t(rows.size());
      for (SimplexId e : reader.vertex_edges(v)) {
        const auto ends = reader.edge_vertices(e);
        rows.push_back(ends[0] == v ? ends[1] : ends[0]);
      }
    }
  }

  // v's neighbours, ascending; v's block must have been filled.
  std::span<const SimplexId> vertex_neighbors(SimplexId v) const {
    const int32_t b = topo_->vertex_block(v);
    const std::vector<SimplexId>& rows = rows_[b];
    const uint32_t end =
        v + 1 == topo_->block_vertex_begin(b + 1) ? uint32_t(rows.size()) : begin_[v + 1];
    return {rows.data() + begin_[v], rows.data() + end};
  }

 private:
  const Topology* topo_;
  std::vector<std::vector<SimplexId>> rows_;  // per block: its vertices' rows back to back
  std::vector<uint32_t> begin_;               // per vertex: its row's start in its block's rows
};

}  // namespace actopo

#endif  // ACTOPO_SERVER_ALGORITHMS_VERTEX_NEIGHBORS_H_
