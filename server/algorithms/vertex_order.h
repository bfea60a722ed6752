// The vertex order every algorithm compares with (simulation of simplicity): vertices sorted by
// (scalar value, input vertex id). Scalars are only reported; plateaus are resolved by id.
//
//   std::vector<SimplexId> order = VertexOrder(*topology, scalars);   // by internal vertex id
//   if (order[u] < order[v]) ...                                      // u is lower than v
#ifndef ACTOPO_SERVER_ALGORITHMS_VERTEX_ORDER_H_
#define ACTOPO_SERVER_ALGORITHMS_VERTEX_ORDER_H_

#include <span>
#include <vector>

#include "server/core/mesh.h"
#include "server/core/topology.h"

namespace actopo {

// scalars: one finite value per input vertex. Returns the rank of each internal vertex. Sorted
// in `threads` runs (0: DefaultThreads()), the same order for any count.
std::vector<SimplexId> VertexOrder(const Topology& topology, std::span<const double> scalars,
                                   int threads = 0);

}  // namespace actopo

#endif  // ACTOPO_SERVER_ALGORITHMS_VERTEX_ORDER_H_
