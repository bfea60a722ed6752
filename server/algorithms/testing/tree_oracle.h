// A brute-force merge tree for tests: every question answered by a search over the mesh's
// edges (taken from its tetrahedra), with none of merge_tree.cc's link scans, union-find or
// sweep. Quadratic or worse: small meshes only.
#ifndef ACTOPO_SERVER_ALGORITHMS_TESTING_TREE_ORACLE_H_
#define ACTOPO_SERVER_ALGORITHMS_TESTING_TREE_ORACLE_H_

#include <algorithm>
#include <functional>
#include <numeric>
#include <set>
#include <utility>
#include <vector>

#include "server/algorithms/merge_tree.h"
#include "server/core/mesh.h"

namespace actopo::testing {

// In input ids, tree sense (down = the leaf side).
struct OracleTree {
  std::vector<std::pair<SimplexId, int>> nodes;               // (vertex, TTK's node type)
  std::vector<std::pair<SimplexId, SimplexId>> arcs;          // (down, up)
  std::vector<std::pair<SimplexId, SimplexId>> segmentation;  // per vertex, its arc's ends
};

inline OracleTree BruteForceMergeTree(const Mesh& mesh, const std::vector<double>& scalars,
                                      TreeType type) {
  const SimplexId n = mesh.num_vertices();
  std::vector<std::set<SimplexId>> adjacent(static_cast<size_t>(n));
  for (SimplexId t = 0; t < mesh.num_tetrahedra(); ++t) {
    for (int i = 0; i < 4; ++i) {
      for (int j = 0; j < 4; ++j) {
        if (i != j) adjacent[mesh.tetrahedra[4 * t + i]].insert(mesh.tetrahedra[4 * t + j]);
      }
    }
  }
  // key: the rank in (scalar, id), reversed for a split tree.
  std::vector<SimplexId> by_rank(static_cast<size_t>(n));
  std::iota(by_rank.begin(), by_rank.end(), 0);
  std::sort(by_rank.begin(), by_rank.end(), [&](SimplexId a, SimplexId b) {
    return std::pair(scalars[a], a) < std::pair(scalars[b], b);
  });
  std::vector<SimplexId> key(static_cast<size_t>(n));
  for (SimplexId r = 0; r < n; ++r) {
    key[by_rank[r]] = type == TreeType::kSplit ? n - 1 - r : r;
  }
  // The vertices reachable from `from` through vertices with key <= limit.
  const auto reach = [&](SimplexId from, SimplexId limit) {
    std::vector<uint8_t> seen(static_cast<size_t>(n), 0);
    std::vector<SimplexId> stack = {from};
    seen[from] = 1;
    while (!stack.empty()) {
      const SimplexId v = stack.back();
      stack.pop_back();
      for (SimplexId w : adjacent[v]) {
        if (!seen[w] && key[w] <= limit) {
          seen[w] = 1;
          stack.push_back(w);
        }
      }
    }
    return seen;
  };

  std::vector<uint8_t> is_node(static_cast<size_t>(n), 0), leaf(static_cast<size_t>(n), 0);
  for (SimplexId v = 0; v < n; ++v) {
    std::vector<int> label(static_cast<size_t>(n), -1);  // strict sublevel components
    int labels = 0;
    std::set<int> lower;
    for (SimplexId w : adjacent[v]) {
      if (key[w] >= key[v]) continue;
      if (label[w] < 0) {
        const std::vector<uint8_t> seen = reach(w, key[v] - 1);
        for (SimplexId u = 0; u < n; ++u) {
          if (seen[u]) label[u] = labels;
        }
        ++labels;
      }
      lower.insert(label[w]);
    }
    if (lower.size() != 1) is_node[v] = 1;
    if (lower.empty()) leaf[v] = 1;
  }
  // Each component's highest vertex is its root: a self-loop if it is a node already.
  std::vector<SimplexId> up(static_cast<size_t>(n), -1);
  std::vector<uint8_t> done(static_cast<size_t>(n), 0);
  for (SimplexId r = n - 1; r >= 0; --r) {
    const SimplexId top = type == TreeType::kSplit ? by_rank[n - 1 - r] : by_rank[r];
    if (done[top]) continue;
    const std::vector<uint8_t> component = reach(top, n);
    for (SimplexId u = 0; u < n; ++u) done[u] |= component[u];
    if (is_node[top]) up[top] = top;
    is_node[top] = 1;
  }
  std::vector<SimplexId> nodes_by_key;
  for (SimplexId v = 0; v < n; ++v) {
    if (is_node[v]) nodes_by_key.push_back(v);
  }
  std::sort(nodes_by_key.begin(), nodes_by_key.end(),
            [&](SimplexId a, SimplexId b) { return key[a] < key[b]; });
  // A node's arc goes up to the lowest higher node it is connected to below that node.
  for (SimplexId a : nodes_by_key) {
    if (up[a] >= 0) continue;
    for (SimplexId b : nodes_by_key) {
      if (key[b] > key[a] && reach(b, key[b])[a]) {
        up[a] = b;
        break;
      }
    }
  }
  OracleTree out;
  std::vector<int> ups(static_cast<size_t>(n), 0), downs(static_cast<size_t>(n), 0);
  for (SimplexId a : nodes_by_key) {
    if (up[a] < 0) continue;
    out.arcs.push_back({a, up[a]});
    ++ups[a];
    ++downs[up[a]];
  }
  for (SimplexId v = 0; v < n; ++v) {
    if (!is_node[v]) continue;
    int u = ups[v], d = downs[v];
    if (type == TreeType::kSplit) std::swap(u, d);
    int t = 4;
    if (u + d == 1)
      t = u == 1 ? 0 : 3;
    else if (u == 2 && d == 1)
      t = 2;
    else if (u == 1 && d == 2)
      t = 1;
    else if (u == 1 && d == 1)
      t = 5;
    out.nodes.push_back({v, t});
  }
  // A regular vertex lies on the arc of the highest node below it in its closed sublevel
  // component; a node on its own arc, or a root without one on the arc that reaches it.
  for (SimplexId v = 0; v < n; ++v) {
    SimplexId below = -1;
    if (is_node[v] && up[v] >= 0) {
      below = v;
    } else if (is_node[v]) {
      for (SimplexId a : nodes_by_key) {
        if (up[a] == v) below = a;
      }
    } else {
      const std::vector<uint8_t> seen = reach(v, key[v]);
      for (SimplexId a : nodes_by_key) {
        if (key[a] < key[v] && seen[a]) below = a;
      }
    }
    out.segmentation.push_back({below, below >= 0 ? up[below] : -1});
  }
  return out;
}

}  // namespace actopo::testing

#endif  // ACTOPO_SERVER_ALGORITHMS_TESTING_TREE_ORACLE_H_
