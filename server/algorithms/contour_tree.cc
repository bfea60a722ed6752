// contour-tree: the join and split trees combined as TTK's FTM combines them (FTMTree_CT:
// insertNodes, then combine after Carr, Snoeyink and Axen), so that nodes, arcs, numbering and
// segmentation are TTK's (docs/trees-plan.md "Contour tree").
//
// Only nodes take part in the combination. Each tree gets the other's nodes inserted into its
// arcs, which cuts its arcs into pieces; combining peels leaf arcs off one tree or the other,
// and every peel makes a contour tree arc, which takes the vertices of the peeled arc's pieces
// that no earlier arc took. A regular vertex therefore lies on the contour arc made by the
// earlier of the two peels that reached its piece in the join tree and in the split tree: no
// per-arc vertex lists are kept.
#include <algorithm>
#include <atomic>
#include <queue>
#include <stack>
#include <utility>

#include "absl/container/flat_hash_map.h"
#include "absl/strings/str_cat.h"
#include "server/algorithms/merge_tree.h"
#include "server/algorithms/tree_sweep.h"
#include "server/core/parallel.h"

namespace actopo::tree_internal {
namespace {

// One merge tree with the other tree's nodes inserted into its arcs. Nodes are numbered as the
// contour tree's candidates (Candidates below), the same in both trees; each node has at most
// one arc up, so arcs are numbered by their down node.
struct AugmentedTree {
  const SweptTree* swept = nullptr;
  std::vector<int32_t> arc_up;             // per arc: its upper node (itself: a self-loop)
  std::vector<uint8_t> has_up;             // per node: its arc up is attached
  std::vector<std::vector<int32_t>> down;  // per node: the arcs attached below it
  // The arc's region: the pieces it holds, a list through next_piece (TTK's concat).
  std::vector<int32_t> head, tail, next_piece;
  std::vector<int32_t> claimed;  // per piece: the contour arc that took its vertices, or -1
  // Per swept node: the candidates inserted on its arc, ascending along the sweep
  // (inserted[inserted_begin[i] .. inserted_begin[i + 1])).
  std::vector<int32_t> inserted_begin, inserted;
  // Per inserted candidate, its rank along the sweep: PieceOf searches these, side by side,
  // rather than a vertex and its order per step.
  std::vector<SimplexId> inserted_key;

  // FTMTree_MT::delNode: a root loses its only arc down; a node with at most one arc down loses
  // its arc up, and its arc down (if any) takes over the upper node and the region.
  void DeleteNode(int32_t k) {
    if (!has_up[k]) {
      if (down[k].size() != 1) return;
      has_up[down[k][0]] = 0;
      down[k].clear();
      return;
    }
    if (down[k].size() >= 2) return;
    const int32_t upper = arc_up[k];
    std::vector<int32_t>& siblings = down[upper];
    siblings.erase(std::find(siblings.begin(), siblings.end(), k));
    has_up[k] = 0;
    if (down[k].size() == 1) {
      const int32_t d = down[k][0];
      arc_up[d] = upper;
      down[upper].push_back(d);
      down[k].clear();
      if (head[k] >= 0) {  // d's region gets k's pieces after its own
        next_piece[tail[d]] = head[k];
        tail[d] = tail[k];
        head[k] = tail[k] = -1;
      }
    }
  }

  // Gives contour arc `ct_arc` the pieces of arc k nobody took yet.
  void Claim(int32_t k, int32_t ct_arc) {
    for (int32_t p = head[k]; p >= 0; p = next_piece[p]) {
      if (claimed[p] < 0) claimed[p] = ct_arc;
    }
  }
};

// The contour tree's candidate nodes: every node of either tree.
struct Candidates {
  std::vector<SimplexId> vertex;  // internal ids
  absl::flat_hash_map<SimplexId, int32_t> of_vertex;
  std::vector<int32_t> of_join, of_split;  // per swept node of each tree
  std::vector<int32_t> component;          // the join tree's component

  int32_t Add(SimplexId v) {
    const auto [it, added] = of_vertex.try_emplace(v, int32_t(vertex.size()));
    if (added) vertex.push_back(v);
    return it->second;
  }
};

// Inserts the candidates that are not nodes of `tree` into its arcs (FTMTree_CT::insertNodes)
// and sets up the pieces.
AugmentedTree Augment(const SweptTree& tree, std::span<const int32_t> of_tree,
                      const Candidates& candidates, std::span<const SimplexId> order) {
  AugmentedTree a;
  a.swept = &tree;
  const size_t n = candidates.vertex.size();
  const size_t swept_nodes = tree.node_vertex.size();
  std::vector<uint8_t> is_tree_node(n, 0);
  for (int32_t k : of_tree) is_tree_node[k] = 1;
  std::vector<std::pair<int32_t, int32_t>> on_arc;  // (swept node, candidate)
  for (size_t k = 0; k < n; ++k) {
    if (!is_tree_node[k]) on_arc.push_back({tree.vertex_node[candidates.vertex[k]], int32_t(k)});
  }
  const auto key = [&](int32_t k) {
    const SimplexId o = order[candidates.vertex[k]];
    return tree.reversed ? -o : o;
  };
  std::sort(on_arc.begin(), on_arc.end(), [&](const auto& x, const auto& y) {
    return x.first != y.first ? x.first < y.first : key(x.second) < key(y.second);
  });
  a.inserted_begin.assign(swept_nodes + 1, 0);
  for (const auto& [node, k] : on_arc) ++a.inserted_begin[node + 1];
  for (size_t i = 0; i < swept_nodes; ++i) a.inserted_begin[i + 1] += a.inserted_begin[i];
  a.inserted.reserve(on_arc.size());
  a.inserted_key.reserve(on_arc.size());
  for (const auto& [node, k] : on_arc) {
    a.inserted.push_back(k);
    a.inserted_key.push_back(key(k));
  }

  a.arc_up.assign(n, -1);
  for (size_t i = 0; i < swept_nodes; ++i) {
    int32_t below = of_tree[i];
    for (int32_t j = a.inserted_begin[i]; j < a.inserted_begin[i + 1]; ++j) {
      a.arc_up[below] = a.inserted[j];
      below = a.inserted[j];
    }
    const int32_t up = tree.node_up[i];
    if (up >= 0) a.arc_up[below] = up == int32_t(i) ? below : of_tree[up];
  }
  a.has_up.assign(n, 0);
  a.down.assign(n, {});
  for (size_t k = 0; k < n; ++k) {
    if (a.arc_up[k] < 0) continue;
    a.has_up[k] = 1;
    a.down[a.arc_up[k]].push_back(int32_t(k));
  }
  a.head.resize(n);
  a.tail.resize(n);
  for (size_t k = 0; k < n; ++k) a.head[k] = a.tail[k] = a.arc_up[k] >= 0 ? int32_t(k) : -1;
  a.next_piece.assign(n, -1);
  a.claimed.assign(n, -1);
  return a;
}

// The piece of augmented tree `a` holding regular vertex v: the arc of the highest candidate
// below v on v's arc of the merge tree.
int32_t PieceOf(const AugmentedTree& a, std::span<const int32_t> of_tree,
                std::span<const SimplexId> order, SimplexId v) {
  const int32_t node = a.swept->vertex_node[v];
  const auto begin = a.inserted_key.begin() + a.inserted_begin[node];
  const auto end = a.inserted_key.begin() + a.inserted_begin[node + 1];
  const SimplexId key = a.swept->reversed ? -order[v] : order[v];
  const auto above = std::lower_bound(begin, end, key);
  return above == begin ? of_tree[node] : a.inserted[size_t(above - a.inserted_key.begin()) - 1];
}

// The contour tree of one run of the forest, appended to `result` (FTMTree_CT::combine, then
// normalizeIds for a contour tree).
class RunCombiner {
 public:
  RunCombiner(AugmentedTree& join, AugmentedTree& split, const Candidates& candidates,
              std::span<const SimplexId> order, std::vector<int32_t>& ct_node_of)
      : join_(join), split_(split), candidates_(candidates), order_(order), ct_of_(ct_node_of) {}

  // Combines, leaves sorted as TTK sorts them (split tree's highest first, join tree's lowest
  // first), and appends nodes and arcs.
  absl::Status Combine(const Topology& topology, std::vector<int32_t> join_leaves,
                       std::vector<int32_t> split_leaves, TreeResult& result) {
    offset_ = int32_t(result.nodes.size());
    first_arc_ = int32_t(result.arcs.size());
    std::queue<std::pair<bool, int32_t>> growing;  // (in the join tree, candidate)
    for (int32_t k : split_leaves) growing.push({false, k});
    if (join_leaves.size() > 1) {
      for (int32_t k : join_leaves) growing.push({true, k});
    }
    size_t stalled = 0;  // requeued in a row: a whole queue of them is a cycle
    while (!growing.empty()) {
      const auto [in_join, k] = growing.front();
      growing.pop();
      AugmentedTree& x = in_join ? join_ : split_;
      AugmentedTree& y = in_join ? split_ : join_;
      if (!x.has_up[k]) continue;
      if (y.down[k].size() > 1) {
        growing.push({in_join, k});
        if (++stalled > growing.size()) {
          return absl::InternalError(
              absl::StrCat("contour-tree: combining the join and split trees stalls at vertex ",
                           topology.vertex_input_id(candidates_.vertex[k])));
        }
        continue;
      }
      stalled = 0;
      const int32_t node1 = NodeFor(k, x.down[k].empty(), topology, result);
      const int32_t parent = x.arc_up[k];
      const int32_t node2 = NodeFor(parent, !x.has_up[parent], topology, result);
      const bool lower = order_[candidates_.vertex[k]] < order_[candidates_.vertex[parent]];
      const int32_t arc = int32_t(result.arcs.size());
      result.arcs.push_back({.down_node = lower ? node1 : node2, .up_node = lower ? node2 : node1});
      x.Claim(k, arc);
      x.DeleteNode(k);
      y.DeleteNode(k);
      if (x.down[parent].empty() && x.has_up[parent]) growing.push({in_join, parent});
    }
    Normalize(result);
    return absl::OkStatus();
  }

 private:
  int32_t NodeFor(int32_t k, bool leaf, const Topology& topology, TreeResult& result) {
    if (ct_of_[k] >= 0) return ct_of_[k];
    ct_of_[k] = int32_t(result.nodes.size());
    result.nodes.push_back({.vertex = topology.vertex_input_id(candidates_.vertex[k])});
    vertex_of_node_.push_back(candidates_.vertex[k]);
    if (leaf) leaves_.push_back(ct_of_[k]);
    return ct_of_[k];
  }

  // normalizeIds for a contour tree: node ids and arc order stay as created; from the leaves in
  // ascending order, the ones with an arc up walk up and number arcs from 0 (a node's arcs up
  // in the order of their upper node), the others walk down and number from the last id down.
  void Normalize(TreeResult& result) {
    const auto order_of = [&](int32_t node) { return order_[vertex_of_node_[node - offset_]]; };
    const size_t num_nodes = result.nodes.size() - size_t(offset_);
    std::vector<std::vector<int32_t>> ups(num_nodes), downs(num_nodes);
    for (int32_t a = first_arc_; a < int32_t(result.arcs.size()); ++a) {
      ups[result.arcs[a].down_node - offset_].push_back(a);
      downs[result.arcs[a].up_node - offset_].push_back(a);
    }
    for (std::vector<int32_t>& list : ups) {
      std::stable_sort(list.begin(), list.end(), [&](int32_t a, int32_t b) {
        return order_of(result.arcs[a].up_node) < order_of(result.arcs[b].up_node);
      });
    }
    std::sort(leaves_.begin(), leaves_.end(),
              [&](int32_t a, int32_t b) { return order_of(a) < order_of(b); });
    std::queue<std::pair<int32_t, bool>> queue;  // (node, walking up)
    std::stack<int32_t> walking_down;
    for (int32_t n : leaves_) {
      if (!ups[n - offset_].empty()) {
        queue.push({n, true});
      } else {
        walking_down.push(n);
      }
    }
    for (; !walking_down.empty(); walking_down.pop()) queue.push({walking_down.top(), false});
    const int32_t num_arcs = int32_t(result.arcs.size()) - first_arc_;
    std::vector<int32_t> id(size_t(num_arcs), -1);
    std::vector<uint8_t> seen_up(size_t(num_arcs), 0), seen_down(size_t(num_arcs), 0);
    int32_t low = 0, high = num_arcs - 1;
    while (!queue.empty()) {
      const auto [n, up] = queue.front();
      queue.pop();
      for (int32_t a : (up ? ups : downs)[n - offset_]) {
        const size_t local = size_t(a - first_arc_);
        if (id[local] < 0) id[local] = up ? low++ : high--;
        uint8_t& seen = (up ? seen_up : seen_down)[local];
        if (!seen) {
          seen = 1;
          queue.push({up ? result.arcs[a].up_node : result.arcs[a].down_node, up});
        }
      }
    }
    // An arc no leaf reaches keeps no id in TTK (a vertex in no tetrahedron, joined to the
    // forest): the ids left over, in creation order.
    for (int32_t& i : id) {
      if (i < 0) i = low++;
    }
    for (int32_t a = 0; a < num_arcs; ++a)
      result.arcs[first_arc_ + a].segmentation_id = offset_ + id[a];
    for (size_t n = 0; n < num_nodes; ++n) {
      result.nodes[offset_ + n].type = NodeType(int(ups[n].size()), int(downs[n].size()));
    }
  }

  AugmentedTree& join_;
  AugmentedTree& split_;
  const Candidates& candidates_;
  std::span<const SimplexId> order_;
  std::vector<int32_t>& ct_of_;  // per candidate, its contour tree node or -1
  int32_t offset_ = 0, first_arc_ = 0;
  std::vector<int32_t> leaves_;            // contour tree nodes made as leaves
  std::vector<SimplexId> vertex_of_node_;  // per node of the run, internal id
};

}  // namespace

absl::StatusOr<TreeResult> BuildContourTree(const Topology& topology,
                                            std::span<const SimplexId> order, SweptTree join,
                                            SweptTree split, int threads) {
  Candidates candidates;
  candidates.of_join.reserve(join.node_vertex.size());
  for (SimplexId v : join.node_vertex) candidates.of_join.push_back(candidates.Add(v));
  for (SimplexId v : split.node_vertex) candidates.of_split.push_back(candidates.Add(v));
  const size_t n = candidates.vertex.size();
  candidates.component.resize(n);
  for (size_t k = 0; k < n; ++k) {
    candidates.component[k] = join.node_component[join.vertex_node[candidates.vertex[k]]];
  }
  for (size_t i = 0; i < join.node_vertex.size(); ++i) {
    candidates.component[candidates.of_join[i]] = join.node_component[i];
  }
  AugmentedTree join_tree = Augment(join, candidates.of_join, candidates, order);
  AugmentedTree split_tree = Augment(split, candidates.of_split, candidates, order);

  TreeResult result;
  result.type = TreeType::kContour;
  MergeTreeNumbering join_numbering(join);
  std::vector<int32_t> ct_of(n, -1);
  const std::vector<std::vector<int32_t>> runs = ForestRuns(topology, join);
  std::vector<int32_t> run_of_component(size_t(join.num_components));
  std::vector<uint8_t> run_is_join(runs.size(), 0);
  for (size_t r = 0; r < runs.size(); ++r) {
    for (int32_t c : runs[r]) run_of_component[c] = int32_t(r);
  }
  const auto leaves_of = [&](const SweptTree& tree, std::span<const int32_t> of_tree, size_t r) {
    std::vector<int32_t> leaves;
    for (size_t i = 0; i < tree.node_vertex.size(); ++i) {
      const int32_t k = of_tree[i];
      if (tree.node_leaf[i] && run_of_component[candidates.component[k]] == int32_t(r)) {
        leaves.push_back(k);
      }
    }
    std::sort(leaves.begin(), leaves.end(), [&](int32_t a, int32_t b) {
      const SimplexId oa = order[candidates.vertex[a]], ob = order[candidates.vertex[b]];
      return tree.reversed ? oa > ob : oa < ob;
    });
    return leaves;
  };
  for (size_t r = 0; r < runs.size(); ++r) {
    std::vector<int32_t> split_leaves = leaves_of(split, candidates.of_split, r);
    if (split_leaves.size() <= 1) {
      // FTM moves the join tree in as the contour tree (the node types' rule is the same).
      run_is_join[r] = 1;
      join_numbering.AppendRun(topology, order, runs[r], result);
      continue;
    }
    result.component_node_begin.push_back(int32_t(result.nodes.size()));
    RunCombiner combiner(join_tree, split_tree, candidates, order, ct_of);
    if (absl::Status s = combiner.Combine(topology, leaves_of(join, candidates.of_join, r),
                                          std::move(split_leaves), result);
        !s.ok()) {
      return s;
    }
  }
  result.component_node_begin.push_back(int32_t(result.nodes.size()));

  // Node vertices: the last arc made that touches them (TTK's segmentation of nodes).
  std::vector<int32_t> last_arc(result.nodes.size(), -1);
  for (size_t a = 0; a < result.arcs.size(); ++a) {
    last_arc[result.arcs[a].down_node] = int32_t(a);
    last_arc[result.arcs[a].up_node] = int32_t(a);
  }
  const SimplexId num_vertices = topology.num_vertices();
  std::vector<uint8_t> is_node(size_t(num_vertices), 0);
  for (size_t k = 0; k < n; ++k) {
    if (ct_of[k] >= 0) is_node[candidates.vertex[k]] = 1;
  }
  for (size_t i = 0; i < join.node_vertex.size(); ++i) {
    if (run_is_join[run_of_component[join.node_component[i]]]) is_node[join.node_vertex[i]] = 1;
  }
  // Each vertex's arc, written over its join tree node once read (each vertex reads only its own).
  std::vector<int32_t>& vertex_arc = join.vertex_node;
  std::atomic<int64_t> lost{0};
  ParallelForRanges(num_vertices, 1 << 14, threads, [&](int64_t begin, int64_t end) {
    for (SimplexId v = SimplexId(begin); v < SimplexId(end); ++v) {
      const int32_t join_node = join.vertex_node[v];
      int32_t arc = -1;
      if (run_is_join[run_of_component[join.node_component[join_node]]]) {
        arc = join_numbering.node_arc()[join_node];
      } else if (is_node[v]) {
        arc = last_arc[ct_of[candidates.of_vertex.at(v)]];
      } else {
        const int32_t j = join_tree.claimed[PieceOf(join_tree, candidates.of_join, order, v)];
        const int32_t s = split_tree.claimed[PieceOf(split_tree, candidates.of_split, order, v)];
        arc = j < 0 ? s : (s < 0 ? j : std::min(j, s));
      }
      vertex_arc[v] = arc;
      if (arc < 0) lost.fetch_add(1, std::memory_order_relaxed);
    }
  });
  if (lost.load() > 0) {
    return absl::InternalError(absl::StrCat("contour-tree: ", lost.load(),
                                            " vertices were left on no arc by the combination"));
  }
  std::vector<int32_t>().swap(split.vertex_node);
  FinishTree(topology, std::move(vertex_arc), is_node, threads, result);
  return result;
}

}  // namespace actopo::tree_internal
