// Invariants every discrete gradient must satisfy (SEMANTICS.md), for tests.
#ifndef ACTOPO_SERVER_ALGORITHMS_TESTING_GRADIENT_CHECKS_H_
#define ACTOPO_SERVER_ALGORITHMS_TESTING_GRADIENT_CHECKS_H_

#include <vector>

#include "gtest/gtest.h"
#include "server/algorithms/discrete_gradient.h"
#include "server/core/explicit_structure.h"

namespace actopo::testing {

// c0 - c1 + c2 - c3 = Euler characteristic; every cell is critical or in exactly one pair, and
// pairs agree in both directions; pairs are facet/cofacet; no closed V-path.
inline void ExpectValidGradient(const DiscreteGradientResult& r, ExplicitStructure& structure) {
  const Topology& topo = structure.topology();
  auto reader = structure.NewReader();
  const GradientField& g = r.gradient;
  const int64_t euler = int64_t(topo.num_vertices()) - topo.num_edges() + topo.num_triangles() -
                        topo.num_tetrahedra();
  EXPECT_EQ(r.critical_cells[0] - r.critical_cells[1] + r.critical_cells[2] - r.critical_cells[3],
            euler);
  auto facets = [&](int d, SimplexId c) -> std::vector<SimplexId> {
    if (d == 1) {
      const auto ev = reader.edge_vertices(c);
      return {ev[0], ev[1]};
    }
    const auto f = d == 2 ? reader.triangle_edges(c) : reader.tetrahedron_triangles(c);
    return {f.begin(), f.end()};
  };
  for (int d = 0; d < 4; ++d) {
    int64_t paired_up = 0, paired_down = 0, critical = 0;
    for (SimplexId c = 0; c < topo.num_simplices(d); ++c) {
      const bool up = d < 3 && g.up[d][c] >= 0;
      const bool down = d > 0 && g.down[d][c] >= 0;
      ASSERT_FALSE(up && down) << "cell " << d << ":" << c << " paired twice";
      critical += !up && !down;
      if (up) {
        ++paired_up;
        ASSERT_EQ(g.down[d + 1][g.up[d][c]], c) << "asymmetric pair at " << d << ":" << c;
        const auto f = facets(d + 1, g.up[d][c]);
        ASSERT_NE(std::find(f.begin(), f.end(), c), f.end()) << "pair is not facet/cofacet";
      }
      paired_down += down;
    }
    EXPECT_EQ(critical, r.critical_cells[d]);
    if (d < 3) {
      EXPECT_EQ(paired_up, r.pairs[d]);
    }
    if (d > 0) {
      EXPECT_EQ(paired_down, r.pairs[d - 1]);
    }
  }
  // V-paths between d- and (d+1)-cells: c -> its pair h -> the other facets of h. Acyclic.
  for (int d = 0; d < 3; ++d) {
    const SimplexId n = topo.num_simplices(d);
    std::vector<uint8_t> state(n, 0);  // 0 new, 1 on stack, 2 done
    std::vector<std::pair<SimplexId, std::vector<SimplexId>>> stack;
    for (SimplexId start = 0; start < n; ++start) {
      if (state[start] != 0) continue;
      auto next = [&](SimplexId c) {
        std::vector<SimplexId> out;
        if (g.up[d][c] < 0) return out;
        for (SimplexId f : facets(d + 1, g.up[d][c])) {
          if (f != c) out.push_back(f);
        }
        return out;
      };
      state[start] = 1;
      stack.push_back({start, next(start)});
      while (!stack.empty()) {
        auto& [c, todo] = stack.back();
        if (todo.empty()) {
          state[c] = 2;
          stack.pop_back();
          continue;
        }
        const SimplexId f = todo.back();
        todo.pop_back();
        ASSERT_NE(state[f], 1) << "closed V-path through " << d << "-cell " << f;
        if (state[f] == 0) {
          state[f] = 1;
          stack.push_back({f, next(f)});
        }
      }
    }
  }
}

}  // namespace actopo::testing

#endif  // ACTOPO_SERVER_ALGORITHMS_TESTING_GRADIENT_CHECKS_H_
