#include "server/algorithms/merge_tree.h"

#include <algorithm>
#include <mutex>
#include <optional>
#include <queue>
#include <thread>
#include <utility>

#include "absl/strings/str_cat.h"
#include "server/algorithms/digest.h"
#include "server/algorithms/link_components.h"
#include "server/algorithms/tree_sweep.h"
#include "server/algorithms/union_find.h"
#include "server/core/actopo_structure.h"
#include "server/core/compact_structure.h"
#include "server/core/explicit_structure.h"
#include "server/core/parallel.h"
#include "server/core/status_macros.h"
#include "server/core/trace.h"

namespace actopo {

std::string_view TreeTypeName(TreeType type) {
  switch (type) {
    case TreeType::kJoin: return "join";
    case TreeType::kSplit: return "split";
    case TreeType::kContour: return "contour";
  }
  return "join";
}

int32_t TreeResult::ComponentOf(int32_t node) const {
  const auto next =
      std::upper_bound(component_node_begin.begin(), component_node_begin.end(), node);
  return int32_t(next - component_node_begin.begin()) - 1;
}

int32_t TreeResult::LocalNodeId(int32_t node) const {
  return node - component_node_begin[size_t(ComponentOf(node))];
}

std::string TreeResult::NodesDigest() const {
  std::vector<std::pair<SimplexId, int>> lines;
  lines.reserve(nodes.size());
  for (const TreeNode& n : nodes) lines.push_back({n.vertex, int(n.type)});
  std::sort(lines.begin(), lines.end());
  StreamedText text;
  for (const auto& [vertex, type] : lines) {
    absl::StrAppend(&text.buffer(), vertex, " ", type, "\n");
    text.Flush();
  }
  return text.HexDigest();
}

std::string TreeResult::ArcsDigest() const {
  std::vector<std::pair<SimplexId, SimplexId>> lines;
  lines.reserve(arcs.size());
  for (const TreeArc& a : arcs)
    lines.push_back({nodes[a.down_node].vertex, nodes[a.up_node].vertex});
  std::sort(lines.begin(), lines.end());
  StreamedText text;
  for (const auto& [down, up] : lines) {
    absl::StrAppend(&text.buffer(), down, " ", up, "\n");
    text.Flush();
  }
  return text.HexDigest();
}

std::string TreeResult::SegmentationDigest() const {
  StreamedText text;
  for (size_t v = 0; v < vertex_arc.size(); ++v) {
    const TreeArc& a = arcs[vertex_arc[v]];
    absl::StrAppend(&text.buffer(), v, " ", nodes[a.down_node].vertex, " ", nodes[a.up_node].vertex,
                    "\n");
    text.Flush();
  }
  return text.HexDigest();
}

RelationSet TreeDeclared() { return {Relation::kVT, Relation::kVV}; }
RelationSet TreeSwept() { return {Relation::kVT}; }

namespace tree_internal {

template <TopologicalStructure Structure>
absl::Status ScanLinks(Structure& structure, std::span<const SimplexId> order,
                       const RunContext& context, LowerLinks* join, LowerLinks* split) {
  const Topology& topo = structure.topology();
  const SimplexId n = topo.num_vertices();
  LowerLinks* sides[2] = {join, split};
  for (LowerLinks* side : sides) {
    if (side != nullptr) side->first.assign(size_t(n), LowerLinks::kLeaf);
  }
  const auto wanted = LinkComponents::Sides((join != nullptr ? LinkComponents::kLower : 0) |
                                            (split != nullptr ? LinkComponents::kUpper : 0));
  bool with_neighbors = false;
  if constexpr (Structure::kRelationsInPlace) {
    with_neighbors = structure.relations().Contains(Relation::kVV);
  }
  // Candidates as (vertex, count, vertices...) records, per side, appended by each consumer.
  std::mutex mu;
  std::vector<SimplexId> records[2];
  const absl::Status status = RunOnConsumers(
      context, topo, topo.num_blocks(), [&](int, BlockRange range, WorkTracker& tracker) {
        auto reader = structure.NewReader();
        LinkComponents link;
        std::vector<SimplexId> found[2];
        std::vector<SimplexId> reps;
        for (int32_t b = range.begin; b < range.end; ++b) {
          for (SimplexId v = topo.block_vertex_begin(b); v < topo.block_vertex_begin(b + 1); ++v) {
            // Where VV is stored: for one tree the groups of neighbours joined by edges, for
            // both the link's masks numbered by VV. Else the masks numbered as the star meets
            // the link, or for a link of more than 63 vertices the general scan.
            bool masked = false;
            if constexpr (Structure::kRelationsInPlace) {
              masked = with_neighbors && (wanted == LinkComponents::kBothSides
                                              ? link.ScanNumbered(reader, v, order, wanted)
                                              : link.ScanByEdges(reader, v, order, wanted));
            }
            if (!masked) masked = link.ScanMasked(reader, v, order, wanted);
            if (!masked) link.Scan(reader, v, order);
            for (int s = 0; s < 2; ++s) {
              if (sides[s] == nullptr) continue;
              const bool want_below = s == 0;
              if (masked) {
                link.MaskedRepresentatives(want_below, reps);
              } else {
                reps.clear();
                for (size_t i = 0; i < link.size(); ++i) {
                  if (link.below(i) == want_below && link.IsRepresentative(i)) {
                    reps.push_back(link.neighbors()[i]);
                  }
                }
              }
              if (reps.size() == 1) sides[s]->first[v] = reps[0];
              if (reps.size() < 2) continue;
              sides[s]->first[v] = -2;
              found[s].push_back(v);
              found[s].push_back(SimplexId(reps.size()));
              found[s].insert(found[s].end(), reps.begin(), reps.end());
            }
          }
          reader.Finished(b);  // a buffering structure drops the block's stars now
          if (!tracker.Done()) return;
        }
        std::lock_guard<std::mutex> lock(mu);
        for (int s = 0; s < 2; ++s)
          records[s].insert(records[s].end(), found[s].begin(), found[s].end());
      });
  if (!status.ok()) return status;
  for (int s = 0; s < 2; ++s) {
    if (sides[s] == nullptr) continue;
    LowerLinks& side = *sides[s];
    side.candidate_begin.assign(1, 0);
    side.candidate_vertices.clear();
    for (size_t i = 0; i < records[s].size();) {
      const SimplexId v = records[s][i], count = records[s][i + 1];
      side.first[v] = -2 - SimplexId(side.candidate_begin.size() - 1);
      side.candidate_vertices.insert(side.candidate_vertices.end(), records[s].begin() + i + 2,
                                     records[s].begin() + i + 2 + count);
      side.candidate_begin.push_back(int64_t(side.candidate_vertices.size()));
      i += 2 + size_t(count);
    }
  }
  return absl::OkStatus();
}

std::vector<SimplexId> VerticesInOrder(std::span<const SimplexId> order, int threads) {
  std::vector<SimplexId> sorted(order.size());
  ParallelForRanges(SimplexId(order.size()), 1 << 16, threads, [&](int64_t begin, int64_t end) {
    for (int64_t v = begin; v < end; ++v) sorted[size_t(order[size_t(v)])] = SimplexId(v);
  });
  return sorted;
}

SweptTree Sweep(const Topology& topology, std::span<const SimplexId> in_order, bool reversed,
                LowerLinks links) {
  const SimplexId n = topology.num_vertices();
  // The k-th vertex of the sweep.
  const auto by_key = [&](SimplexId k) { return in_order[size_t(reversed ? n - 1 - k : k)]; };

  SweptTree tree;
  tree.reversed = reversed;
  const auto new_node = [&tree](SimplexId v, bool leaf) {
    tree.node_vertex.push_back(v);
    tree.node_up.push_back(-1);
    tree.node_leaf.push_back(leaf);
    return int32_t(tree.node_vertex.size() - 1);
  };
  // The union-find's root of a component is always its latest node's vertex, and a node's
  // vertex holds its node index in `arc_node` (which reuses links.first in place): a regular
  // vertex's arc is then its component root's.
  std::vector<SimplexId>& arc_node = links.first;
  UnionFind components(static_cast<size_t>(n));
  std::vector<SimplexId> roots;
  // The sweep visits the vertices in the order, all over the mesh: each step's reads would miss
  // the cache. They are fetched ahead in two steps: the vertex's own entries, then (once those
  // are in) the union-find entry of its lower neighbour.
  constexpr SimplexId kAhead = 16;
  for (SimplexId k = 0; k < n; ++k) {
    if (k + kAhead < n) {
      const SimplexId ahead = by_key(k + kAhead);
      __builtin_prefetch(&arc_node[ahead]);
      components.Prefetch(ahead);
    }
    if (k + kAhead / 2 < n) {
      const SimplexId lower = arc_node[by_key(k + kAhead / 2)];
      if (lower >= 0) components.Prefetch(lower);
    }
    const SimplexId v = by_key(k);
    const SimplexId first = arc_node[v];
    if (first == LowerLinks::kLeaf) {
      arc_node[v] = new_node(v, true);
      continue;
    }
    roots.clear();
    if (first >= 0) {
      roots.push_back(components.Find(first));
    } else {
      const SimplexId c = -2 - first;
      for (int64_t i = links.candidate_begin[c]; i < links.candidate_begin[c + 1]; ++i) {
        roots.push_back(components.Find(links.candidate_vertices[i]));
      }
      std::sort(roots.begin(), roots.end());
      roots.erase(std::unique(roots.begin(), roots.end()), roots.end());
    }
    if (roots.size() == 1) {
      components.Link(v, roots[0]);
      arc_node[v] = arc_node[roots[0]];
      continue;
    }
    const int32_t saddle = new_node(v, false);
    arc_node[v] = saddle;
    for (SimplexId root : roots) {
      tree.node_up[arc_node[root]] = saddle;
      components.Link(root, v);
    }
  }
  // Each component's highest vertex closes its last arc: a self-loop when it is a node already.
  const size_t swept_nodes = tree.node_vertex.size();
  std::vector<int32_t> component_of_root(swept_nodes, -1);
  int32_t components_left = 0;
  for (size_t i = 0; i < swept_nodes; ++i) components_left += tree.node_up[i] < 0;
  tree.num_components = components_left;
  std::vector<int32_t> root_node;  // per component, its last node before the top
  for (SimplexId k = n - 1; k >= 0 && components_left > 0; --k) {
    const SimplexId v = by_key(k);
    const SimplexId root = components.Find(v);
    const int32_t last = arc_node[root];
    if (component_of_root[last] >= 0) continue;
    component_of_root[last] = int32_t(root_node.size());
    root_node.push_back(last);
    --components_left;
    tree.node_up[last] = v == root ? last : new_node(v, false);
  }
  // Components: numbered from their highest vertex down; `node_component` through the roots.
  tree.node_component.resize(tree.node_vertex.size());
  for (size_t i = 0; i < tree.node_vertex.size(); ++i) {
    tree.node_component[i] = component_of_root[arc_node[components.Find(tree.node_vertex[i])]];
  }
  if (tree.num_components > 1) {
    tree.component_first_tetrahedron.assign(size_t(tree.num_components), -1);
    for (SimplexId t = 0; t < topology.num_tetrahedra(); ++t) {
      const SimplexId root = components.Find(topology.tetrahedron(t)[0]);
      SimplexId& first = tree.component_first_tetrahedron[component_of_root[arc_node[root]]];
      const SimplexId id = topology.tetrahedron_input_id(t);
      if (first < 0 || id < first) first = id;
    }
  }
  tree.vertex_node = std::move(arc_node);
  return tree;
}

std::vector<std::vector<int32_t>> ForestRuns(const Topology& topology, const SweptTree& tree) {
  std::vector<int32_t> with_tetrahedra, without;
  for (int32_t c = 0; c < tree.num_components; ++c) {
    (tree.num_components == 1 || tree.component_first_tetrahedron[c] >= 0 ? with_tetrahedra
                                                                          : without)
        .push_back(c);
  }
  if (with_tetrahedra.size() <= 1) {
    with_tetrahedra.insert(with_tetrahedra.end(), without.begin(), without.end());
    return {with_tetrahedra};
  }
  std::sort(with_tetrahedra.begin(), with_tetrahedra.end(), [&](int32_t a, int32_t b) {
    return tree.component_first_tetrahedron[a] < tree.component_first_tetrahedron[b];
  });
  // A vertex in no tetrahedron is a one-node component: after the others, by input id (TTK's
  // output is undefined there).
  std::vector<SimplexId> vertex_of(size_t(tree.num_components));
  for (size_t i = 0; i < tree.node_vertex.size(); ++i) {
    vertex_of[tree.node_component[i]] = topology.vertex_input_id(tree.node_vertex[i]);
  }
  std::sort(without.begin(), without.end(),
            [&](int32_t a, int32_t b) { return vertex_of[a] < vertex_of[b]; });
  std::vector<std::vector<int32_t>> runs;
  for (int32_t c : with_tetrahedra) runs.push_back({c});
  for (int32_t c : without) runs.push_back({c});
  return runs;
}

CriticalType NodeType(int up_arcs, int down_arcs) {
  if (up_arcs + down_arcs == 1)
    return up_arcs == 1 ? CriticalType::kMinimum : CriticalType::kMaximum;
  if (up_arcs == 2 && down_arcs == 1) return CriticalType::kSaddle2;
  if (up_arcs == 1 && down_arcs == 2) return CriticalType::kSaddle1;
  if (up_arcs == 1 && down_arcs == 1) return CriticalType::kRegular;
  return CriticalType::kDegenerate;
}

int8_t RegionType(CriticalType a, CriticalType b) {
  const auto either = [&](CriticalType t) { return a == t || b == t; };
  if (either(CriticalType::kMinimum)) return 0;
  if (either(CriticalType::kMaximum)) return 1;
  if (a == CriticalType::kSaddle1 && b == CriticalType::kSaddle1) return 2;
  if (a == CriticalType::kSaddle2 && b == CriticalType::kSaddle2) return 3;
  return 4;
}

void FinishTree(const Topology& topology, std::vector<int32_t> vertex_arc,
                std::span<const uint8_t> internal_is_node, int threads, TreeResult& result) {
  result.counts = {};
  for (const TreeNode& node : result.nodes) ++result.counts[int(node.type)];
  // Per node: its down and up arc counts and the first of each (arcs in cell order).
  const size_t num_nodes = result.nodes.size();
  std::vector<int32_t> downs(num_nodes, 0), ups(num_nodes, 0), first_down(num_nodes, -1),
      first_up(num_nodes, -1);
  for (size_t i = 0; i < result.arcs.size(); ++i) {
    const TreeArc& a = result.arcs[i];
    if (downs[a.up_node]++ == 0) first_down[a.up_node] = int32_t(i);
    if (ups[a.down_node]++ == 0) first_up[a.down_node] = int32_t(i);
  }
  for (size_t n = 0; n < num_nodes; ++n) {
    int32_t& arc = result.nodes[n].region_arc;
    if (downs[n] == 1) {
      arc = first_down[n];
    } else if (ups[n] == 1) {
      arc = first_up[n];
    } else {
      arc = first_down[n] >= 0 ? first_down[n] : first_up[n];
    }
  }
  for (TreeArc& a : result.arcs) {
    a.region_type = RegionType(result.nodes[a.down_node].type, result.nodes[a.up_node].type);
    a.region_size = 0;
  }
  for (size_t v = 0; v < vertex_arc.size(); ++v) {
    if (!internal_is_node[v]) ++result.arcs[vertex_arc[v]].region_size;
  }
  // From internal to input ids: a gather, in parallel. Walking the permutation's cycles in
  // place would save this array but is a chain of dependent cache misses on a mesh whose input
  // order is unrelated to the blocks'.
  std::vector<int32_t> by_input(vertex_arc.size());
  ParallelForRanges(SimplexId(vertex_arc.size()), 1 << 16, threads,
                    [&](int64_t begin, int64_t end) {
                      for (SimplexId v = SimplexId(begin); v < end; ++v) {
                        by_input[size_t(topology.vertex_input_id(v))] = vertex_arc[size_t(v)];
                      }
                    });
  std::vector<int32_t>().swap(vertex_arc);
  result.vertex_arc = std::move(by_input);
}

MergeTreeNumbering::MergeTreeNumbering(const SweptTree& tree)
    : tree_(tree),
      node_arc_(tree.node_vertex.size(), -1),
      up_arcs_(tree.node_vertex.size(), 0),
      down_arcs_(tree.node_vertex.size(), 0),
      component_nodes_(size_t(tree.num_components)) {
  for (size_t i = 0; i < tree.node_vertex.size(); ++i) {
    component_nodes_[tree.node_component[i]].push_back(int32_t(i));
    if (tree.node_up[i] < 0) continue;
    ++up_arcs_[i];
    ++down_arcs_[tree.node_up[i]];
  }
}

void MergeTreeNumbering::AppendRun(const Topology& topology, std::span<const SimplexId> order,
                                   std::span<const int32_t> run, TreeResult& result) {
  std::vector<int32_t> nodes;
  for (int32_t c : run) {
    nodes.insert(nodes.end(), component_nodes_[c].begin(), component_nodes_[c].end());
  }
  std::sort(nodes.begin(), nodes.end(),
            [&](int32_t a, int32_t b) { return tree_.Key(order, a) < tree_.Key(order, b); });
  const int32_t offset = int32_t(result.nodes.size());
  result.component_node_begin.push_back(offset);
  std::vector<int32_t> node_id(tree_.node_vertex.size());  // only this run's entries are set
  for (size_t k = 0; k < nodes.size(); ++k) {
    const int32_t i = nodes[k];
    node_id[i] = offset + int32_t(k);
    const CriticalType t = tree_.reversed ? NodeType(down_arcs_[i], up_arcs_[i])
                                          : NodeType(up_arcs_[i], down_arcs_[i]);
    result.nodes.push_back({topology.vertex_input_id(tree_.node_vertex[i]), t});
  }
  const size_t first_arc = result.arcs.size();
  for (int32_t i : nodes) {
    if (tree_.node_up[i] < 0) continue;
    node_arc_[i] = int32_t(result.arcs.size());
    result.arcs.push_back({.down_node = node_id[i], .up_node = node_id[tree_.node_up[i]]});
  }
  // Breadth-first from the leaves in NodeId order: a node's arc gets the next id the first
  // time the node is met, and its upper node is queued then.
  std::vector<uint8_t> seen(result.arcs.size() - first_arc, 0);
  std::queue<int32_t> queue;
  for (int32_t i : nodes) {
    if (tree_.node_leaf[i]) queue.push(i);
  }
  int32_t next = 0;
  while (!queue.empty()) {
    const int32_t i = queue.front();
    queue.pop();
    const int32_t a = node_arc_[i];
    if (a < 0 || seen[size_t(a) - first_arc]) continue;
    seen[size_t(a) - first_arc] = 1;
    result.arcs[a].segmentation_id = offset + next++;
    queue.push(tree_.node_up[i]);
  }
}

namespace {

// TTK's numbering of a join or split tree (FTMTree_MT::normalizeIds with sortNodes and
// sortArcs), run by run of the forest.
TreeResult NumberMergeTree(const Topology& topology, std::span<const SimplexId> order,
                           TreeType type, SweptTree tree, int threads) {
  TreeResult result;
  result.type = type;
  MergeTreeNumbering numbering(tree);
  for (const std::vector<int32_t>& run : ForestRuns(topology, tree)) {
    numbering.AppendRun(topology, order, run, result);
  }
  result.component_node_begin.push_back(int32_t(result.nodes.size()));
  std::vector<uint8_t> is_node(size_t(topology.num_vertices()), 0);
  for (SimplexId v : tree.node_vertex) is_node[v] = 1;
  std::vector<int32_t> vertex_arc = std::move(tree.vertex_node);  // node index -> its arc
  for (int32_t& x : vertex_arc) x = numbering.node_arc()[x];
  FinishTree(topology, std::move(vertex_arc), is_node, threads, result);
  return result;
}

}  // namespace
}  // namespace tree_internal

template <TopologicalStructure Structure>
absl::StatusOr<TreeResult> RunTree(Structure& structure, std::span<const SimplexId> order,
                                   TreeType type, const RunContext& context) {
  using namespace tree_internal;
  const Topology& topology = structure.topology();
  Trace* trace = context.trace.get();
  const bool join = type != TreeType::kSplit, split = type != TreeType::kJoin;
  LowerLinks join_links, split_links;
  {
    Trace::Scope span(trace, "link scan", "phase");
    RETURN_IF_ERROR(ScanLinks(structure, order, context, join ? &join_links : nullptr,
                              split ? &split_links : nullptr));
  }
  std::optional<SweptTree> join_tree, split_tree;
  {
    Trace::Scope span(trace, "sweep", "phase");
    const std::vector<SimplexId> in_order = VerticesInOrder(order, context.consumers);
    // The contour tree's two sweeps are independent: side by side when there are two consumers.
    std::thread split_thread;
    if (split) {
      const auto sweep_split = [&] {
        split_tree = Sweep(topology, in_order, true, std::move(split_links));
      };
      if (join && context.consumers > 1) {
        split_thread = std::thread(sweep_split);
      } else {
        sweep_split();
      }
    }
    if (join) join_tree = Sweep(topology, in_order, false, std::move(join_links));
    if (split_thread.joinable()) split_thread.join();
  }
  Trace::Scope span(trace, type == TreeType::kContour ? "combine" : "numbering", "phase");
  if (type == TreeType::kContour) {
    return BuildContourTree(topology, order, *std::move(join_tree), *std::move(split_tree),
                            context.consumers);
  }
  return NumberMergeTree(topology, order, type, *std::move(join ? join_tree : split_tree),
                         context.consumers);
}

#define ACTOPO_INSTANTIATE(S)                                                                   \
  template absl::StatusOr<TreeResult> RunTree(S&, std::span<const SimplexId>, TreeType,         \
                                              const RunContext&);                               \
  template absl::Status tree_internal::ScanLinks(S&, std::span<const SimplexId>,                \
                                                 const RunContext&, tree_internal::LowerLinks*, \
                                                 tree_internal::LowerLinks*);
ACTOPO_FOR_EACH_STRUCTURE(ACTOPO_INSTANTIATE)
#undef ACTOPO_INSTANTIATE

}  // namespace actopo
