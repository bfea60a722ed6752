#include "server/algorithms/vertex_order.h"

#include <algorithm>
#include <numeric>

namespace actopo {

std::vector<SimplexId> VertexOrder(const Topology& topology, std::span<const double> scalars) {
  const SimplexId n = topology.num_vertices();
  std::vector<SimplexId> by_rank(n);  // input ids, ascending (scalar, id)
  std::iota(by_rank.begin(), by_rank.end(), 0);
  std::sort(by_rank.begin(), by_rank.end(), [&](SimplexId a, SimplexId b) {
    return scalars[a] < scalars[b] || (scalars[a] == scalars[b] && a < b);
  });
  std::vector<SimplexId> order(n);
  for (SimplexId rank = 0; rank < n; ++rank)
    order[topology.vertex_internal_id(by_rank[rank])] = rank;
  return order;
}

}  // namespace actopo
