// Block-local computation of every relation (the TopoCluster / ACTOPO unit of work).
//
// ComputeBlockRelation(topology, R, b, scratch) returns relation R for every simplex internal to
// block b (those whose lowest vertex is in b), using only the static encoding: b's internal and
// external tetrahedra plus tuple -> id lookups. Results follow the canonical orders of
// relation.h, so every structure that stores or caches them answers identically.
//
//   BlockScratch scratch;  // one per thread, reused: no allocation once warmed up
//   RelationBlock vt = ComputeBlockRelation(*topology, Relation::kVT, b, scratch);
//   std::span<const SimplexId> star = vt.row(v - vt.first);
//
// Work is linear in the block's tetrahedra (counting sorts into flat arrays); the only
// exception is the tetrahedron adjacency TT across triangles owned by other blocks, which scans
// the external tetrahedra of those blocks (still linear, in the neighbours' sizes).
#ifndef ACTOPO_SERVER_CORE_BLOCK_RELATIONS_H_
#define ACTOPO_SERVER_CORE_BLOCK_RELATIONS_H_

#include <cstdint>
#include <span>
#include <vector>

#include "server/core/link_edges.h"
#include "server/core/mesh.h"
#include "server/core/relation.h"
#include "server/core/topology.h"

namespace actopo {

// One relation of one block: rows for the block's internal simplices [first, first + count).
// Fixed-size relations (FE, TE, TF, predicates) have stride > 0 and no offsets.
struct RelationBlock {
  Relation relation = Relation::kVV;
  int32_t block = -1;
  SimplexId first = 0;
  SimplexId count = 0;
  int32_t stride = 0;
  std::vector<SimplexId> offsets;  // count + 1 when stride == 0
  std::vector<SimplexId> values;

  std::span<const SimplexId> row(SimplexId i) const {
    if (stride > 0) return {values.data() + size_t(i) * stride, size_t(stride)};
    return {values.data() + offsets[i], values.data() + offsets[i + 1]};
  }
  int64_t bytes() const {
    return int64_t(offsets.capacity() + values.capacity()) * int64_t(sizeof(SimplexId)) +
           int64_t(sizeof(RelationBlock));
  }
};

// A triangle (sorted vertices) and the number of tetrahedra seen with it, up to 2 (VB).
struct TriangleCount {
  SimplexId a = -1, b = -1, c = -1;  // a == -1: an empty slot
  int32_t count = 0;
};

// Reusable per-thread buffers.
struct BlockScratch {
  std::vector<SimplexId> rows, values, counts, mark, tmp, candidates;
  std::vector<int64_t> keys;
  std::vector<TriangleCount> triangles;  // VB: an open-addressing table
  LinkVertexIndex link_vertices;         // a vertex's neighbours (VV), a block's candidates
};

// Computes R (not a static relation: EV, FV, TV, FB live in the topology) for block b.
RelationBlock ComputeBlockRelation(const Topology& topology, Relation r, int32_t b,
                                   BlockScratch& scratch);

}  // namespace actopo

#endif  // ACTOPO_SERVER_CORE_BLOCK_RELATIONS_H_
