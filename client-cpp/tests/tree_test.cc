// merge-tree and contour-tree: the trees read back from the streamed arrays (ResultArrays::Tree)
// hold together (counts as the summary's, leaves with one arc, every vertex on one arc), their
// global NodeIds give the summary's digests (which the server computes from its own tree, not
// from the wire's component-relative ids), on a mesh of two components too, and on
// fertility_tet.vtu they equal upstream TTK's (expected-ttk.json under the data directory).
#include <algorithm>
#include <cmath>
#include <map>
#include <numeric>
#include <set>

#include "absl/strings/str_cat.h"
#include "src/internal/sha256.h"
#include "tests/testing/fixture.h"
#include "tests/testing/lattice.h"

namespace actopo::client::testing {
namespace {

using absl::StatusCode;

std::string Sha256Hex(const std::string& text) {
  internal::Sha256 sha;
  sha.Update(std::as_bytes(std::span(text)));
  absl::StatusOr<std::string> hex = sha.HexDigest();
  EXPECT_TRUE(hex.ok()) << hex.status();
  return hex.ok() ? *hex : "";
}

// The summary's digests computed from the tree as read (the server's TreeResult::NodesDigest,
// ArcsDigest, SegmentationDigest): nodes as "<vertex> <type>" sorted, arcs as "<down vertex> <up
// vertex>" sorted, every vertex as "<v> <down vertex> <up vertex>" of the arc it lies on.
std::map<std::string, std::string> Digests(const ScalarTree& tree) {
  std::vector<std::pair<int64_t, int>> nodes;
  for (const ScalarTree::Node& n : tree.nodes) nodes.push_back({n.vertex, n.critical_type});
  std::sort(nodes.begin(), nodes.end());
  std::string text;
  for (const auto& [vertex, type] : nodes) absl::StrAppend(&text, vertex, " ", type, "\n");
  std::map<std::string, std::string> digests = {{"nodes_sha256", Sha256Hex(text)}};

  std::vector<std::pair<int64_t, int64_t>> arcs;
  std::map<int64_t, const ScalarTree::Arc*> by_segmentation;
  for (const ScalarTree::Arc& a : tree.arcs) {
    arcs.push_back({tree.nodes[size_t(a.down_node)].vertex, tree.nodes[size_t(a.up_node)].vertex});
    by_segmentation[a.segmentation_id] = &a;
  }
  std::sort(arcs.begin(), arcs.end());
  text.clear();
  for (const auto& [down, up] : arcs) absl::StrAppend(&text, down, " ", up, "\n");
  digests["arcs_sha256"] = Sha256Hex(text);

  text.clear();
  for (size_t v = 0; v < tree.segmentation.size(); ++v) {
    const auto it = by_segmentation.find(tree.segmentation[v]);
    if (it == by_segmentation.end()) {  // ExpectConsistent says why
      digests["segmentation_sha256"] = "";
      return digests;
    }
    absl::StrAppend(&text, v, " ", tree.nodes[size_t(it->second->down_node)].vertex, " ",
                    tree.nodes[size_t(it->second->up_node)].vertex, "\n");
  }
  digests["segmentation_sha256"] = Sha256Hex(text);
  return digests;
}

// What holds for any tree of kind `kind` ("join", "split", "contour") of a mesh of `vertices`
// vertices, against the job's summary (with digests).
void ExpectConsistent(const ScalarTree& tree, const nlohmann::json& summary,
                      const std::string& kind, int64_t vertices) {
  SCOPED_TRACE(kind);
  EXPECT_EQ(summary["tree"], kind);
  const size_t n = tree.nodes.size();
  EXPECT_EQ(int64_t(n), summary["nodes"].get<int64_t>());
  EXPECT_EQ(int64_t(tree.arcs.size()), summary["arcs"].get<int64_t>());
  std::map<std::string, int64_t> types;
  for (const ScalarTree::Node& node : tree.nodes) ++types[std::to_string(node.critical_type)];
  EXPECT_EQ(nlohmann::json(types), summary["critical_types"]);

  // A forest over the nodes: no arc closes a cycle, and each of its trees is in one component.
  std::vector<size_t> parent(n);
  std::iota(parent.begin(), parent.end(), 0);
  const auto root = [&](size_t x) {
    while (parent[x] != x) x = parent[x] = parent[parent[x]];
    return x;
  };
  std::vector<int> as_down(n, 0), as_up(n, 0);
  int64_t on_arcs = 0;
  std::set<int64_t> segmentation_ids;
  for (size_t i = 0; i < tree.arcs.size(); ++i) {
    const ScalarTree::Arc& a = tree.arcs[i];
    ASSERT_TRUE(a.down_node >= 0 && a.down_node < int64_t(n) && a.up_node >= 0 &&
                a.up_node < int64_t(n))
        << "arc " << i << ": " << a.down_node << " -> " << a.up_node;
    const ScalarTree::Node &down = tree.nodes[size_t(a.down_node)],
                           &up = tree.nodes[size_t(a.up_node)];
    on_arcs += a.region_size;
    EXPECT_TRUE(segmentation_ids.insert(a.segmentation_id).second)
        << "SegmentationId " << a.segmentation_id << " twice";
    if (a.down_node == a.up_node) {  // a vertex in no tetrahedron: its node, alone
      EXPECT_EQ(down.critical_type, 5) << "arc " << i;
      EXPECT_EQ(a.region_size, 0) << "arc " << i;
      continue;
    }
    const size_t d = root(size_t(a.down_node)), u = root(size_t(a.up_node));
    EXPECT_NE(d, u) << "arc " << i << " closes a cycle";
    parent[d] = u;
    ++as_down[size_t(a.down_node)];
    ++as_up[size_t(a.up_node)];
    // The down node is the leaf side: lower in a join or contour tree, higher in a split tree.
    if (kind == "split") {
      EXPECT_GE(down.scalar, up.scalar) << "arc " << i;
    } else {
      EXPECT_LE(down.scalar, up.scalar) << "arc " << i;
    }
  }
  int64_t trees = 0;
  for (size_t i = 0; i < n; ++i) trees += root(i) == i;
  EXPECT_GE(trees, summary["components"].get<int64_t>());
  EXPECT_EQ(int64_t(tree.component_offsets.size()) - 1, summary["components"].get<int64_t>());
  EXPECT_EQ(on_arcs + int64_t(n), vertices);  // every vertex a node or on one arc

  // Extrema have one arc: a join tree's minima (its leaves) and a split tree's maxima are its
  // down end and the up end of none; the other extrema (a merge tree's roots, a contour tree's
  // maxima) the reverse.
  const int leaf_type = kind == "split" ? 3 : 0;
  for (size_t i = 0; i < n; ++i) {
    const int type = tree.nodes[i].critical_type;
    EXPECT_EQ(tree.nodes[i].id, int64_t(i));
    if (type != 0 && type != 3) continue;
    EXPECT_EQ(as_down[i], type == leaf_type ? 1 : 0) << "node " << i << " of type " << type;
    EXPECT_EQ(as_up[i], type == leaf_type ? 0 : 1) << "node " << i << " of type " << type;
  }

  // Every vertex on an arc; a node's vertex on one of that node's arcs.
  ASSERT_EQ(int64_t(tree.segmentation.size()), vertices);
  for (size_t v = 0; v < tree.segmentation.size(); ++v) {
    ASSERT_TRUE(segmentation_ids.contains(tree.segmentation[v]))
        << "vertex " << v << ": SegmentationId " << tree.segmentation[v] << " is no arc's";
  }
  for (const ScalarTree::Node& node : tree.nodes) {
    const int64_t id = tree.segmentation[size_t(node.vertex)];
    const auto arc =
        std::find_if(tree.arcs.begin(), tree.arcs.end(),
                     [&](const ScalarTree::Arc& a) { return a.segmentation_id == id; });
    EXPECT_TRUE(arc->down_node == node.id || arc->up_node == node.id)
        << "node " << node.id << " (vertex " << node.vertex << ") lies on arc " << arc->down_node
        << " -> " << arc->up_node;
  }

  // The digests of the server's own tree, from the ids as read.
  const std::map<std::string, std::string> digests = Digests(tree);
  for (const char* key : {"nodes_sha256", "arcs_sha256", "segmentation_sha256"}) {
    ASSERT_TRUE(summary.contains(key)) << summary.dump();
    EXPECT_EQ(digests.at(key), summary[key]) << key;
  }
}

class TreeTest : public ServerTest {
 protected:
  // A job of `algorithm` with digests; its tree read back, checked against its summary.
  absl::StatusOr<JobResult> RunTree(const std::string& session, const std::string& algorithm,
                                    const std::map<std::string, std::string>& parameters,
                                    const std::string& kind, int64_t vertices) {
    absl::StatusOr<JobResult> result =
        client().RunJob(session, algorithm, parameters, {.digests = true});
    if (!result.ok()) return result;
    EXPECT_EQ(result->algorithm, algorithm);
    absl::StatusOr<ScalarTree> tree = result->Tree();
    EXPECT_TRUE(tree.ok()) << tree.status();
    if (tree.ok()) {
      ExpectConsistent(*tree, nlohmann::json::parse(result->summary_json), kind, vertices);
    }
    return result;
  }
};

TEST_F(TreeTest, JoinSplitAndContourTreesOfASample) {
  const std::string mesh = LoadSample("jittered:12");
  absl::StatusOr<MeshInfo> info = client().GetMesh(mesh);
  ASSERT_OK(info);
  const std::string session = Open(mesh, {.structure = Structure::kCompact});
  absl::StatusOr<JobResult> join = RunTree(session, "merge-tree", {}, "join", info->vertices);
  ASSERT_OK(join);
  absl::StatusOr<JobResult> named =
      RunTree(session, "merge-tree", {{"tree", "join"}}, "join", info->vertices);
  ASSERT_OK(named);
  EXPECT_EQ(nlohmann::json::parse(named->summary_json), nlohmann::json::parse(join->summary_json));
  absl::StatusOr<JobResult> split =
      RunTree(session, "merge-tree", {{"tree", "split"}}, "split", info->vertices);
  ASSERT_OK(split);
  absl::StatusOr<JobResult> contour =
      RunTree(session, "contour-tree", {}, "contour", info->vertices);
  ASSERT_OK(contour);

  // On one component the wire's relative ids are the NodeIds.
  absl::StatusOr<ScalarTree> tree = split->Tree();
  ASSERT_OK(tree);
  absl::StatusOr<std::vector<int32_t>> down = split->Get<int32_t>("tree_arcs/downNodeId");
  ASSERT_OK(down);
  ASSERT_EQ(down->size(), tree->arcs.size());
  for (size_t i = 0; i < down->size(); ++i) EXPECT_EQ((*down)[i], tree->arcs[i].down_node);
  // A simplified field's tree has at most as many nodes.
  absl::StatusOr<JobResult> simplified =
      RunTree(session, "merge-tree", {{"tree", "split"}, {"relative_threshold", "0.05"}}, "split",
              info->vertices);
  ASSERT_OK(simplified);
  const auto first = simplified->arrays.lower_bound("simplified/");
  EXPECT_TRUE(first != simplified->arrays.end() && first->first.starts_with("simplified/"));
  absl::StatusOr<ScalarTree> fewer = simplified->Tree();
  ASSERT_OK(fewer);
  EXPECT_LE(fewer->nodes.size(), tree->nodes.size());
}

// fertility height: every tree's digests, from the ids as read, equal upstream TTK's.
TEST_F(TreeTest, FertilityTreesEqualTtks) {
  const nlohmann::json ttk = TtkReference("fertility_tet.vtu", "height", "merge_trees");
  const std::string mesh = Fertility();
  absl::StatusOr<MeshInfo> info = client().GetMesh(mesh);
  ASSERT_OK(info);
  const std::string session = Open(mesh, {.scalar = "height", .consumers = 2});
  const struct {
    const char* algorithm;
    std::map<std::string, std::string> parameters;
    const char* kind;
    const char* section;
  } cases[] = {{"merge-tree", {}, "join", "join_tree"},
               {"merge-tree", {{"tree", "split"}}, "split", "split_tree"},
               {"contour-tree", {}, "contour", "contour_tree"}};
  for (const auto& c : cases) {
    absl::StatusOr<JobResult> result =
        RunTree(session, c.algorithm, c.parameters, c.kind, info->vertices);
    ASSERT_OK(result) << c.kind;
    absl::StatusOr<ScalarTree> tree = result->Tree();
    ASSERT_OK(tree);
    const nlohmann::json& want = ttk[c.section];
    EXPECT_EQ(int64_t(tree->nodes.size()), want["nodes"].get<int64_t>()) << c.kind;
    EXPECT_EQ(int64_t(tree->arcs.size()), want["arcs"].get<int64_t>()) << c.kind;
    const std::map<std::string, std::string> digests = Digests(*tree);
    for (const char* key : {"nodes_sha256", "arcs_sha256", "segmentation_sha256"}) {
      EXPECT_EQ(digests.at(key), want[key]) << c.kind << " " << key;
    }
  }
}

// Each field of a job over fields reads its tree as a job on that field alone does.
TEST_F(TreeTest, ATreePerField) {
  absl::StatusOr<MeshInfo> info = client().GetMesh(Fertility());
  ASSERT_OK(info);
  const std::string session = Open(Fertility(), {.structure = Structure::kCompact});
  absl::StatusOr<JobResult> result = client().RunJob(
      session, "contour-tree", {}, {.digests = true, .fields = {"height", "eigenfunction4"}});
  ASSERT_OK(result);
  ASSERT_EQ(result->fields.size(), 2u);
  for (const FieldResult& field : result->fields) {
    const nlohmann::json ttk = TtkReference("fertility_tet.vtu", field.field, "merge_trees");
    absl::StatusOr<ScalarTree> tree = field.Tree();
    ASSERT_OK(tree) << field.field;
    ExpectConsistent(*tree, nlohmann::json::parse(field.summary_json), "contour", info->vertices);
    EXPECT_EQ(Digests(*tree).at("arcs_sha256"), ttk["contour_tree"]["arcs_sha256"]) << field.field;
  }
  EXPECT_TRUE(HasError(result->Tree(), StatusCode::kNotFound, "'tree_nodes/NodeId' not found"));
}

// Two lattices side by side (the second moved by `shift` in x, its field + `lift`), and
// optionally two vertices in no tetrahedron: two components (four), whose arcs but the first
// one's have ids relative to their first node on the wire.
class TwoComponentsTest : public TreeTest {
 protected:
  std::string Upload(double shift, double lift, bool isolated = false) {
    const int64_t nv = lattice_.vertices();
    std::vector<double> points = lattice_.points, field;
    // A field of several extrema per axis, so that each tree has saddles.
    for (int64_t v = 0; v < nv; ++v) {
      const double x = lattice_.points[3 * v], y = lattice_.points[3 * v + 1],
                   z = lattice_.points[3 * v + 2];
      field.push_back(std::sin(7 * x + 1) * std::cos(5 * y) + std::sin(6 * z + 2 * x) +
                      1e-3 * lattice_.height[size_t(v)]);
    }
    std::vector<int64_t> tetrahedra = lattice_.tetrahedra;
    for (int64_t v = 0; v < nv; ++v) {
      points.insert(points.end(), {lattice_.points[3 * v] + shift, lattice_.points[3 * v + 1],
                                   lattice_.points[3 * v + 2]});
      field.push_back(field[size_t(v)] + lift);
    }
    for (int64_t id : lattice_.tetrahedra) tetrahedra.push_back(id + nv);
    if (isolated) {  // one far away, one inside the first lattice
      points.insert(points.end(), {-3, -3, -3, 0.5, 0.5, 0.5});
      field.insert(field.end(), {0.3, 0.7});
    }
    components_ = isolated ? 4 : 2;
    vertices_ = int64_t(field.size());
    return Keep(client().UploadMesh(points, tetrahedra, {{"height", field}}, {.name = "two"}));
  }

  // Every tree of the mesh read back and checked; the second component's arcs are shifted.
  void ExpectTrees(const std::string& mesh) {
    const int64_t nv = lattice_.vertices();
    const std::string session = Open(mesh, {.structure = Structure::kExplicit});
    for (const auto& [algorithm, kind] : std::vector<std::pair<std::string, std::string>>{
             {"merge-tree", "join"}, {"merge-tree", "split"}, {"contour-tree", "contour"}}) {
      std::map<std::string, std::string> parameters;
      if (algorithm == "merge-tree") parameters["tree"] = kind;
      absl::StatusOr<JobResult> result = RunTree(session, algorithm, parameters, kind, vertices_);
      ASSERT_OK(result) << kind;
      EXPECT_EQ(nlohmann::json::parse(result->summary_json)["components"], components_) << kind;
      absl::StatusOr<ScalarTree> tree = result->Tree();
      ASSERT_OK(tree);
      absl::StatusOr<std::vector<int32_t>> down = result->Get<int32_t>("tree_arcs/downNodeId");
      ASSERT_OK(down);
      absl::StatusOr<std::vector<int32_t>> component =
          result->Get<int32_t>("tree_arcs/ComponentId");
      ASSERT_OK(component);
      ASSERT_EQ(int64_t(tree->component_offsets.size()), components_ + 1) << kind;
      EXPECT_GT(tree->arcs.size(), 4u) << kind;
      for (size_t i = 0; i < tree->arcs.size(); ++i) {
        const ScalarTree::Arc& a = tree->arcs[i];
        const int64_t dv = tree->nodes[size_t(a.down_node)].vertex,
                      uv = tree->nodes[size_t(a.up_node)].vertex;
        EXPECT_EQ(dv < nv, uv < nv) << kind << " arc " << i << " joins two components";
        EXPECT_EQ(dv >= 2 * nv, uv >= 2 * nv) << kind << " arc " << i << " joins two components";
        EXPECT_EQ(a.down_node != (*down)[i], dv >= nv) << kind << " arc " << i;
        EXPECT_EQ(a.component, (*component)[i]) << kind << " arc " << i;
        EXPECT_EQ(a.down_node - (*down)[i], tree->component_offsets[size_t(a.component)])
            << kind << " arc " << i;
      }
    }
  }

  Lattice lattice_{8};
  int64_t vertices_ = 0, components_ = 0;
};

TEST_F(TwoComponentsTest, ApartWithOtherValues) { ExpectTrees(Upload(100, 1000)); }

// A vertex in no tetrahedron is a tree of its own: one node and an arc from it to itself.
TEST_F(TwoComponentsTest, AndVerticesInNoTetrahedron) { ExpectTrees(Upload(100, 1000, true)); }

TEST_F(TreeTest, BadTreeParametersAndMissingArrays) {
  const std::string session = Open(LoadSample("jittered:8"), {.structure = Structure::kCompact});
  EXPECT_TRUE(HasError(client().RunJob(session, "merge-tree", {{"tree", "contour"}}),
                       StatusCode::kInvalidArgument,
                       "parameters.tree: unknown value 'contour'; available: join, split"));
  EXPECT_TRUE(HasError(client().RunJob(session, "contour-tree", {{"tree", "join"}}),
                       StatusCode::kInvalidArgument,
                       "parameters: unknown parameter 'tree' for contour-tree"));
  EXPECT_TRUE(HasError(client().RunJob(session, "merge-tree", {{"relative_threshold", "x"}}),
                       StatusCode::kInvalidArgument, "parameters.relative_threshold"));
  absl::StatusOr<JobResult> lean =
      client().RunJob(session, "merge-tree", {}, {.include_arrays = false});
  ASSERT_OK(lean);
  EXPECT_GT(nlohmann::json::parse(lean->summary_json)["nodes"].get<int64_t>(), 0);
  EXPECT_TRUE(HasError(lean->Tree(), StatusCode::kNotFound, "include_arrays"));
  absl::StatusOr<JobResult> points = client().RunJob(session, "critical-points");
  ASSERT_OK(points);
  EXPECT_TRUE(HasError(points->Tree(), StatusCode::kNotFound, "'tree_nodes/NodeId' not found"));
}

}  // namespace
}  // namespace actopo::client::testing
