// ResultArrays::Tree: the tree_nodes/, tree_arcs/ and segmentation/ arrays of a merge-tree or
// contour-tree job (TTK's three outputs) read back into a ScalarTree.
//
// TTK writes an arc's upNodeId and downNodeId relative to the first NodeId of the arc's
// connected component. Beside TTK's arrays the server streams a ComponentId of its own per node
// (tree_nodes/ComponentId: 0, 1, ... over NodeId, each component a run of NodeIds) and per arc
// (tree_arcs/ComponentId), so an end's global NodeId is its local id plus the first NodeId whose
// ComponentId is the arc's.
#include <string>
#include <utility>
#include <vector>

#include "absl/strings/str_cat.h"
#include "actopo/client.h"
#include "src/internal/columns.h"

namespace actopo::client {
namespace {

// What a missing array's NOT_FOUND says.
constexpr char kFromWhere[] =
    "a tree comes from a merge-tree or contour-tree job run with JobOptions::include_arrays";

}  // namespace

absl::StatusOr<ScalarTree> ResultArrays::Tree() const {
  const internal::Columns columns(*this, "", kFromWhere);
  for (const char* name : {"tree_nodes/ComponentId", "tree_arcs/ComponentId"}) {
    if (Find(name) == nullptr && Find("tree_nodes/NodeId") != nullptr) {
      return absl::NotFoundError(absl::StrCat("result array '", name,
                                              "' not found: the server streams it beside TTK's "
                                              "arrays (a server older than this client does not)"));
    }
  }
  // The nodes: NodeId counts them and must be 0, 1, ...
  absl::StatusOr<std::vector<int64_t>> ids = columns.Integers("tree_nodes/NodeId", -1, "");
  if (!ids.ok()) return ids.status();
  const size_t n = ids->size();
  for (size_t i = 0; i < n; ++i) {
    if ((*ids)[i] != int64_t(i)) {
      return columns.Malformed("tree_nodes/NodeId",
                               absl::StrCat("entry ", i, " is ", (*ids)[i], ", not ", i,
                                            ": the nodes are not by NodeId"));
    }
  }
  constexpr char kPerNode[] = "one per node";
  absl::StatusOr<std::vector<double>> node_scalar =
      columns.Reals("tree_nodes/Scalar", int64_t(n), kPerNode);
  if (!node_scalar.ok()) return node_scalar.status();
  absl::StatusOr<std::vector<int64_t>> vertex =
      columns.Integers("tree_nodes/VertexId", int64_t(n), kPerNode);
  if (!vertex.ok()) return vertex.status();
  absl::StatusOr<std::vector<int64_t>> type =
      columns.Integers("tree_nodes/CriticalType", int64_t(n), kPerNode);
  if (!type.ok()) return type.status();
  absl::StatusOr<std::vector<int64_t>> node_size =
      columns.Integers("tree_nodes/RegionSize", int64_t(n), kPerNode);
  if (!node_size.ok()) return node_size.status();
  absl::StatusOr<std::vector<double>> node_span =
      columns.Reals("tree_nodes/RegionSpan", int64_t(n), kPerNode, /*any_dtype=*/true);
  if (!node_span.ok()) return node_span.status();
  // The components: ComponentId 0, 1, ... over NodeId, each a run of NodeIds. first[k] is
  // component k's first NodeId, first.back() the node count.
  absl::StatusOr<std::vector<int64_t>> node_component =
      columns.Integers("tree_nodes/ComponentId", int64_t(n), kPerNode);
  if (!node_component.ok()) return node_component.status();
  std::vector<int64_t> first;
  for (size_t i = 0; i < n; ++i) {
    const int64_t k = (*node_component)[i], next = int64_t(first.size());
    if (k == next) {
      first.push_back(int64_t(i));
    } else if (k != next - 1) {
      return columns.Malformed(
          "tree_nodes/ComponentId",
          absl::StrCat("node ", i, " is in component ", k,
                       i == 0 ? ", not 0" : absl::StrCat(" after ", next - 1),
                       ": not 0, 1, 2, ... over NodeId, each component a run"));
    }
  }
  first.push_back(int64_t(n));

  // The arcs: upNodeId counts them.
  constexpr char kPerArc[] = "one per arc";
  absl::StatusOr<std::vector<int64_t>> up = columns.Integers("tree_arcs/upNodeId", -1, "");
  if (!up.ok()) return up.status();
  const size_t a = up->size();
  absl::StatusOr<std::vector<int64_t>> down =
      columns.Integers("tree_arcs/downNodeId", int64_t(a), kPerArc);
  if (!down.ok()) return down.status();
  absl::StatusOr<std::vector<int64_t>> segmentation_id =
      columns.Integers("tree_arcs/SegmentationId", int64_t(a), kPerArc);
  if (!segmentation_id.ok()) return segmentation_id.status();
  absl::StatusOr<std::vector<int64_t>> arc_size =
      columns.Integers("tree_arcs/RegionSize", int64_t(a), kPerArc);
  if (!arc_size.ok()) return arc_size.status();
  absl::StatusOr<std::vector<double>> arc_span =
      columns.Reals("tree_arcs/RegionSpan", int64_t(a), kPerArc, /*any_dtype=*/true);
  if (!arc_span.ok()) return arc_span.status();
  absl::StatusOr<std::vector<int64_t>> arc_component =
      columns.Integers("tree_arcs/ComponentId", int64_t(a), kPerArc);
  if (!arc_component.ok()) return arc_component.status();
  absl::StatusOr<std::vector<int64_t>> segmentation =
      columns.Integers("segmentation/SegmentationId", -1, "");
  if (!segmentation.ok()) return segmentation.status();

  ScalarTree tree;
  tree.nodes.resize(n);
  for (size_t i = 0; i < n; ++i) {
    if ((*type)[i] < 0 || (*type)[i] > 5) {
      return columns.Malformed(
          "tree_nodes/CriticalType",
          absl::StrCat("node ", i, " has type ", (*type)[i], "; a node's is 0 to 5"));
    }
    tree.nodes[i] = {.id = int64_t(i),
                     .vertex = (*vertex)[i],
                     .scalar = (*node_scalar)[i],
                     .critical_type = int((*type)[i]),
                     .region_size = (*node_size)[i],
                     .region_span = (*node_span)[i]};
  }
  tree.segmentation = *std::move(segmentation);
  tree.component_offsets = first;
  // An end's global NodeId: its local id plus its arc's component's first NodeId.
  tree.arcs.resize(a);
  for (size_t i = 0; i < a; ++i) {
    const int64_t k = (*arc_component)[i];
    if (k < 0 || k >= int64_t(first.size()) - 1) {
      return columns.Malformed("tree_arcs/ComponentId",
                               absl::StrCat("arc ", i, " is in component ", k,
                                            ", but tree_nodes/ComponentId has ", first.size() - 1));
    }
    const int64_t count = first[size_t(k) + 1] - first[size_t(k)];
    for (const auto& [name, local] : {std::pair{"tree_arcs/downNodeId", (*down)[i]},
                                      std::pair{"tree_arcs/upNodeId", (*up)[i]}}) {
      if (local < 0 || local >= count) {
        return columns.Malformed(name, absl::StrCat("arc ", i, " has ", local, ", not within the ",
                                                    count, " nodes of its component (", k, ")"));
      }
    }
    tree.arcs[i] = {.down_node = first[size_t(k)] + (*down)[i],
                    .up_node = first[size_t(k)] + (*up)[i],
                    .segmentation_id = (*segmentation_id)[i],
                    .region_size = (*arc_size)[i],
                    .region_span = (*arc_span)[i],
                    .component = k};
  }
  return tree;
}

}  // namespace actopo::client
