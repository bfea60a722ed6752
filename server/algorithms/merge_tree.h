// merge-tree and contour-tree: TTK's MergeTree and ContourTree (its FTM backend on tetrahedra),
// with TTK's nodes, arcs, numbering and segmentation (SEMANTICS.md "merge-tree, contour-tree").
//
// The join tree follows the connected components of the sublevel sets {f < c} as c rises: its
// nodes are the vertices where a component is born (no lower neighbour: a leaf), where two or
// more components merge (lower neighbours in two or more components, over the edges: a saddle)
// and each connected component's highest vertex (its root). The split tree is the join tree of
// the reversed order. Each arc holds the regular vertices between its two nodes.
//
// How it is computed (docs/trees-plan.md): one parallel scan of every vertex's star (VT, like
// critical points: no edges, no triangles) gives one vertex of each component of its lower
// link; a sequential sweep in the vertex order then joins vertices with union-find, whose root
// per component is its latest node. Only vertices whose lower link has two or more components
// are checked for a merge. The scan keeps each link as bit masks (LinkComponents::ScanMasked);
// where VV is stored (explicit) it numbers the link by it (ScanNumbered) for the contour tree's
// two sides, and for one tree groups the lower neighbours by the edges between them
// (ScanByEdges), all a merge needs; compact and actopo would compute VV only to save less than
// it costs. The contour tree's two sweeps run side by side.
//
//   ASSIGN_OR_RETURN(TreeResult join, RunTree(*structure, order, TreeType::kJoin, context));
//   for (const TreeArc& a : join.arcs) ... join.nodes[a.down_node].vertex ...
//   std::string digest = join.ArcsDigest();  // equals expected-ttk.json's arcs_sha256
#ifndef ACTOPO_SERVER_ALGORITHMS_MERGE_TREE_H_
#define ACTOPO_SERVER_ALGORITHMS_MERGE_TREE_H_

#include <array>
#include <cstdint>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "absl/status/statusor.h"
#include "server/algorithms/consumers.h"
#include "server/algorithms/critical_points.h"
#include "server/core/relation.h"
#include "server/core/structures.h"

namespace actopo {

// TTK's TreeType values.
enum class TreeType : uint8_t { kJoin = 0, kSplit = 1, kContour = 2 };
std::string_view TreeTypeName(TreeType type);  // "join", "split", "contour"

struct TreeNode {
  SimplexId vertex = 0;  // input id
  // TTK's node type from the node's arcs (docs/trees-plan.md): 0 a leaf of the join tree or the
  // root of the split tree, 3 the reverse, 1 and 2 saddles, 4 degenerate (a k-way merge for
  // k >= 3, a root that is also a saddle), 5 regular (a one-vertex component).
  CriticalType type = CriticalType::kRegular;
  // The arc whose RegionSize and RegionSpan the node reports, as TTK picks it: its only down
  // arc, else its only up arc, else its first down arc (its first up arc when it has none).
  int32_t region_arc = 0;
};

struct TreeArc {
  // NodeIds in the tree's sense: the down node is the leaf side (the higher end in a split tree).
  int32_t down_node = 0;
  int32_t up_node = 0;
  int32_t segmentation_id = 0;  // TTK's SegmentationId: normalized arc id + component offset
  int32_t region_size = 0;      // the arc's regular vertices (nodes excluded)
  // TTK's RegionType from the two nodes' types: 0 an end is a minimum, else 1 an end is a
  // maximum, else 2 both 1-saddles, 3 both 2-saddles, 4 otherwise.
  int8_t region_type = 4;
};

struct TreeResult {
  TreeType type = TreeType::kJoin;
  std::vector<TreeNode> nodes;  // by NodeId
  std::vector<TreeArc> arcs;    // in TTK's arc cell order
  // The NodeIds of component k (of TTK's forest) are [component_node_begin[k],
  // component_node_begin[k + 1]): TTK writes upNodeId and downNodeId relative to it.
  std::vector<int32_t> component_node_begin;
  // Per input vertex, the index in `arcs` of its arc; a node's vertex gets the last arc (in cell
  // order) that touches it, as TTK's segmentation does.
  std::vector<int32_t> vertex_arc;
  std::array<int64_t, 6> counts{};  // nodes per CriticalType

  // The component (of TTK's forest, 0, 1, ...) of a node.
  int32_t ComponentOf(int32_t node) const;
  // A NodeId relative to its component's first, as TTK's upNodeId and downNodeId are.
  int32_t LocalNodeId(int32_t node) const;
  // SHA-256 of "<input vertex> <type>\n" per node, ascending vertex.
  std::string NodesDigest() const;
  // SHA-256 of "<down vertex> <up vertex>\n" per arc (input ids, tree sense), sorted as pairs.
  std::string ArcsDigest() const;
  // SHA-256 of "<v> <down vertex> <up vertex>\n" for every input vertex v ascending: the ends
  // of the arc it lies on.
  std::string SegmentationDigest() const;
};

// VT: the star of each vertex, whose other vertices are its link (as critical points); and
// VV, read only where the structure stores it (explicit).
RelationSet TreeDeclared();
// VT: what actopo's producers compute ahead.
RelationSet TreeSwept();

// The join tree (kJoin), split tree (kSplit) or contour tree (kContour) of the order `order`
// (VertexOrder(), by internal id). Defined for the explicit, compact and actopo structures.
template <TopologicalStructure Structure>
absl::StatusOr<TreeResult> RunTree(Structure& structure, std::span<const SimplexId> order,
                                   TreeType type, const RunContext& context);

}  // namespace actopo

#endif  // ACTOPO_SERVER_ALGORITHMS_MERGE_TREE_H_
