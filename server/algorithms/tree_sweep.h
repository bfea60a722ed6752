// The steps the merge and contour trees share (merge_tree.h): the star scan that finds each
// vertex's lower-link components, the sweep that builds one merge tree from them, and TTK's
// forest of components. Internal to the algorithms library.
#ifndef ACTOPO_SERVER_ALGORITHMS_TREE_SWEEP_H_
#define ACTOPO_SERVER_ALGORITHMS_TREE_SWEEP_H_

#include <cstdint>
#include <span>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "server/algorithms/consumers.h"
#include "server/algorithms/merge_tree.h"
#include "server/core/topology.h"

namespace actopo::tree_internal {

// For one direction of the order (the join tree's, or the split tree's reversed one): per
// internal vertex, one vertex of its lower link if that link is one component.
struct LowerLinks {
  static constexpr SimplexId kLeaf = -1;  // no lower neighbour
  // kLeaf; a lower neighbour (>= 0); or -2 - k for candidate k, whose lower link has two or more
  // components: one vertex of each is candidate_vertices[candidate_begin[k] ..
  // candidate_begin[k + 1]).
  std::vector<SimplexId> first;
  std::vector<int64_t> candidate_begin;
  std::vector<SimplexId> candidate_vertices;
};

// One scan of every vertex's star fills the join side (lower link), the split side (upper
// link), or both (null: not wanted).
template <TopologicalStructure Structure>
absl::Status ScanLinks(Structure& structure, std::span<const SimplexId> order,
                       const RunContext& context, LowerLinks* join, LowerLinks* split);

// One merge tree before TTK's numbering, nodes in creation order.
struct SweptTree {
  bool reversed = false;               // a split tree: the sweep ran down the order
  std::vector<SimplexId> node_vertex;  // internal ids
  // The node at the upper end (tree sense) of the node's arc: itself for a self-loop (a
  // component whose highest vertex was already a node), -1 for a component's root.
  std::vector<int32_t> node_up;
  std::vector<uint8_t> node_leaf;       // born without a lower neighbour
  std::vector<int32_t> node_component;  // 0 .. num_components - 1
  // Per internal vertex: the node whose arc holds it (TTK's rule for the nodes themselves).
  std::vector<int32_t> vertex_node;
  int32_t num_components = 0;
  // Per component, its lowest input tetrahedron id (-1: a vertex in no tetrahedron); filled
  // only when there are several components.
  std::vector<SimplexId> component_first_tetrahedron;

  // The node's rank along the sweep (ascending order for a join tree, descending for split).
  SimplexId Key(std::span<const SimplexId> order, int32_t node) const {
    const SimplexId o = order[node_vertex[node]];
    return reversed ? SimplexId(order.size()) - 1 - o : o;
  }
};

// The vertices by rank in `order` (its inverse), on `threads`.
std::vector<SimplexId> VerticesInOrder(std::span<const SimplexId> order, int threads);

// The sweep in the order (reversed for a split tree), `in_order` the vertices by rank in it
// (VerticesInOrder); consumes `links`.
SweptTree Sweep(const Topology& topology, std::span<const SimplexId> in_order, bool reversed,
                LowerLinks links);

// TTK's forest (docs/trees-plan.md "Components"): the components, each run on its own, in the
// order of their lowest input tetrahedron, then the vertices in no tetrahedron; or everything as
// one forest when at most one component has tetrahedra. Lists each run's components.
std::vector<std::vector<int32_t>> ForestRuns(const Topology& topology, const SweptTree& tree);

// TTK's numbering of a join or split tree (FTMTree_MT::normalizeIds with sortNodes and
// sortArcs), one run of the forest at a time: NodeIds along the sweep, arcs in the order of
// their down node, normalized arc ids handed out breadth-first from the leaves.
class MergeTreeNumbering {
 public:
  explicit MergeTreeNumbering(const SweptTree& tree);
  // Appends the run's nodes and arcs to `result` (its component_node_begin too).
  void AppendRun(const Topology& topology, std::span<const SimplexId> order,
                 std::span<const int32_t> run, TreeResult& result);
  // Per swept node, the index in result.arcs of its arc (-1: none, or not appended yet).
  std::span<const int32_t> node_arc() const { return node_arc_; }

 private:
  const SweptTree& tree_;
  std::vector<int32_t> node_arc_;
  std::vector<int> up_arcs_, down_arcs_;
  std::vector<std::vector<int32_t>> component_nodes_;
};

// The contour tree of a join tree and a split tree of the same order (contour_tree.cc).
absl::StatusOr<TreeResult> BuildContourTree(const Topology& topology,
                                            std::span<const SimplexId> order, SweptTree join,
                                            SweptTree split, int threads);

// TTK's node type from the node's arc counts in the tree's sense (a self-loop counts on both).
CriticalType NodeType(int up_arcs, int down_arcs);
// TTK's RegionType of an arc between nodes of these types.
int8_t RegionType(CriticalType a, CriticalType b);
// Counts, region sizes and types and each node's region arc, once nodes and arcs are numbered;
// `vertex_arc` (each internal vertex's arc) becomes result.vertex_arc, by input id, gathered
// on `threads`.
void FinishTree(const Topology& topology, std::vector<int32_t> vertex_arc,
                std::span<const uint8_t> internal_is_node, int threads, TreeResult& result);

}  // namespace actopo::tree_internal

#endif  // ACTOPO_SERVER_ALGORITHMS_TREE_SWEEP_H_
