// Walking a discrete gradient's V-paths, the one way every algorithm that follows them does.
//
// Descending, from a vertex: vertex -> its paired edge -> the edge's other vertex -> ... until a
// critical vertex (a minimum). Reads only the vertex -> edge pairing and the edges' vertices: no
// relation.
//
//   const SimplexId minimum = DescendToMinimum(topo, g, v);
//   WalkDown(topo, g, v, [&](SimplexId edge, SimplexId next) { path.push_back(edge); ... });
//
// Ascending, from a tetrahedron, through the links the gradient's sweep records
// (AscendingLinks::up: per tetrahedron the next one up, the boundary's code, or a maximum's):
//
//   const SimplexId end = ClimbLinks(up, t, [&](SimplexId from, SimplexId to) { ... });
//   if (end == LinkCode::kBoundary) ...; else maximum = LinkCode::Label(end);
#ifndef ACTOPO_SERVER_ALGORITHMS_GRADIENT_PATHS_H_
#define ACTOPO_SERVER_ALGORITHMS_GRADIENT_PATHS_H_

#include <span>

#include "server/algorithms/discrete_gradient.h"
#include "server/core/topology.h"

namespace actopo {

// The vertex after non-critical vertex v on its descending V-path.
inline SimplexId NextVertexDown(const Topology& topo, const GradientField& g, SimplexId v) {
  const auto ev = topo.edge(g.up[0][v]);
  return ev[0] == v ? ev[1] : ev[0];
}

// Follows v's descending V-path to its minimum, calling step(edge, next_vertex) for each edge
// crossed; returns the minimum. A valid gradient's paths descend, so they end.
template <class Step>
SimplexId WalkDown(const Topology& topo, const GradientField& g, SimplexId v, Step&& step) {
  while (!g.IsCritical(0, v)) {
    const SimplexId edge = g.up[0][v];
    const auto ev = topo.edge(edge);
    v = ev[0] == v ? ev[1] : ev[0];
    step(edge, v);
  }
  return v;
}

inline SimplexId DescendToMinimum(const Topology& topo, const GradientField& g, SimplexId v) {
  return WalkDown(topo, g, v, [](SimplexId, SimplexId) {});
}

// The codes an ascending link holds where a path ends: below every tetrahedron id, -1 for the
// boundary and -2 - L for label L (a maximum's index). Code and Label are each other's inverse
// (the same map), and Code(-1) is the boundary's.
struct LinkCode {
  static constexpr SimplexId kBoundary = -1;
  static constexpr SimplexId Code(SimplexId label) { return -2 - label; }
  static constexpr SimplexId Label(SimplexId code) { return -2 - code; }
  static constexpr bool IsEnd(SimplexId entry) { return entry < 0; }
};

// Follows `up` from tetrahedron t while its entries are tetrahedra, calling step(from, to) for
// each move; returns the final code (LinkCode). A valid gradient's paths ascend, so they end.
template <class Step>
SimplexId ClimbLinks(std::span<const SimplexId> up, SimplexId t, Step&& step) {
  while (!LinkCode::IsEnd(up[t])) {
    step(t, up[t]);
    t = up[t];
  }
  return up[t];
}

}  // namespace actopo

#endif  // ACTOPO_SERVER_ALGORITHMS_GRADIENT_PATHS_H_
