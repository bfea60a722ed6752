// Whether a vertex is on the boundary (VB), for the IsOnBoundary arrays of result outputs.
//
//   auto boundary = std::make_shared<const VertexBoundary>(*topology);
//   bool on = (*boundary)(v);   // v: internal id; its block's VB computed on first need, kept
#ifndef ACTOPO_SERVER_RESULTS_VERTEX_BOUNDARY_H_
#define ACTOPO_SERVER_RESULTS_VERTEX_BOUNDARY_H_

#include <cstdint>
#include <span>
#include <vector>

#include "server/core/block_relations.h"
#include "server/core/sync.h"
#include "server/core/topology.h"

namespace actopo {

// Whether a vertex (internal id) is on the boundary (VB), computed for its block when first
// asked and kept (a byte per vertex at most). Outputs ask it for their critical cells' highest
// vertices only, so only the blocks holding those are computed, not every block of the mesh.
// Thread-safe.
class VertexBoundary {
 public:
  explicit VertexBoundary(const Topology& topology);
  bool operator()(SimplexId v) const;
  // Computes the blocks of `vertices` (internal ids) not computed yet on `threads` threads, so
  // that asking for those vertices then only reads. A Morse-Smale result's critical cells lie in
  // most blocks of the mesh, too many to compute on one thread.
  void Prepare(std::span<const SimplexId> vertices, int threads) const;
  int32_t blocks_computed() const;

 private:
  const Topology& topology_;
  mutable Mutex mu_;
  mutable std::vector<std::vector<uint8_t>> blocks_ ABSL_GUARDED_BY(mu_);  // empty: not yet
  mutable BlockScratch scratch_ ABSL_GUARDED_BY(mu_);
  mutable int32_t computed_ ABSL_GUARDED_BY(mu_) = 0;
};

}  // namespace actopo

#endif  // ACTOPO_SERVER_RESULTS_VERTEX_BOUNDARY_H_
