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
//   std::vector<SimplexId> row;                    // one per thread
//   for (SimplexId u : kept.vertex_neighbors(v, row)) ...
#ifndef ACTOPO_SERVER_ALGORITHMS_VERTEX_NEIGHBORS_H_
#define ACTOPO_SERVER_ALGORITHMS_VERTEX_NEIGHBORS_H_

#include <climits>
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
    std::vector<int16_t>& codes = rows_[b];
    codes.clear();
    codes.reserve(size);  // exact unless a neighbour is far
    for (SimplexId v = first; v < last; ++v) {
      begin_[v] = uint32_t(codes.size());
      for (SimplexId e : reader.vertex_edges(v)) {
        const auto ends = reader.edge_vertices(e);
        Append(v, ends[0] == v ? ends[1] : ends[0], codes);
      }
    }
    if (codes.size() != size) codes.shrink_to_fit();
  }

  // v's neighbours, ascending, decoded into `row` (what it held is replaced; the span points
  // into it); v's block must have been filled. Thread-safe with other readers.
  std::span<const SimplexId> vertex_neighbors(SimplexId v, std::vector<SimplexId>& row) const {
    const int32_t b = topo_->vertex_block(v);
    const std::vector<int16_t>& codes = rows_[b];
    const size_t end =
        v + 1 == topo_->block_vertex_begin(b + 1) ? codes.size() : size_t(begin_[v + 1]);
    row.clear();
    for (size_t i = begin_[v]; i < end; ++i) {
      if (codes[i] != kFar) {
        row.push_back(v + codes[i]);
      } else {
        row.push_back(SimplexId(uint32_t(uint16_t(codes[i + 1])) << 16 | uint16_t(codes[i + 2])));
        i += 2;
      }
    }
    return row;
  }

 private:
  // A neighbour u of v is kept as u - v in 16 bits when it fits (nearly all of them: vertices are
  // numbered block by block, and most neighbours lie in the same block or one numbered close to
  // it), else as kFar and u's two halves. About 2 bytes a neighbour instead of 4, held from the
  // diagram's gradient to the simplification's end, which lowers the simplified Morse-Smale
  // complex's peak.
  static constexpr int16_t kFar = INT16_MIN;
  static void Append(SimplexId v, SimplexId u, std::vector<int16_t>& codes) {
    const int64_t d = int64_t(u) - int64_t(v);
    if (d > INT16_MIN && d <= INT16_MAX) {
      codes.push_back(int16_t(d));
    } else {
      codes.push_back(kFar);
      codes.push_back(int16_t(uint16_t(uint32_t(u) >> 16)));
      codes.push_back(int16_t(uint16_t(uint32_t(u) & 0xffffu)));
    }
  }

  const Topology* topo_;
  std::vector<std::vector<int16_t>> rows_;  // per block: its vertices' rows back to back
  std::vector<uint32_t> begin_;             // per vertex: its row's start in its block's rows
};

}  // namespace actopo

#endif  // ACTOPO_SERVER_ALGORITHMS_VERTEX_NEIGHBORS_H_
