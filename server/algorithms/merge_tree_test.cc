#include "server/algorithms/merge_tree.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <set>
#include <tuple>

#include "gtest/gtest.h"
#include "server/algorithms/link_components.h"
#include "server/algorithms/persistence_diagram.h"
#include "server/algorithms/testing/tree_oracle.h"
#include "server/algorithms/union_find.h"
#include "server/algorithms/vertex_order.h"
#include "server/core/actopo_structure.h"
#include "server/core/compact_structure.h"
#include "server/core/explicit_structure.h"
#include "server/core/partition.h"
#include "server/core/testing/status.h"
#include "server/core/testing/test_meshes.h"

namespace actopo {
namespace {

using testing::OracleTree;

struct Case {
  std::string name;
  Mesh mesh;
  std::vector<double> scalars;
};

// Two tetrahedra sharing only their highest vertex: the join tree's root is a saddle, closed by
// a self-loop; and one vertex in no tetrahedron.
Mesh PinchedWithIsolatedPoint() {
  Mesh m;
  m.points = {0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 5,  // 0-3: first tet, 3 the shared top
              2, 0, 0, 3, 0, 0, 2, 1, 0,           // 4-6: second tet
              9, 9, 9};                            // 7: isolated
  m.tetrahedra = {0, 1, 2, 3, 4, 5, 6, 3};
  m.point_fields.push_back({"height", {0.5, 1, 2, 10, 0, 1.5, 3, 4}});
  return m;
}

// A vertex with 72 neighbours, more than LinkComponents::ScanNumbered takes: the centre of a
// ring of 70 whose vertices alternate low and high, so its lower link is 35 single vertices (a
// 35-way merge) and its upper link one ring with the two apexes.
Mesh WideSaddle() {
  Mesh m = testing::Bipyramid(70, true);
  std::vector<double>& f = m.point_fields[0].values;
  f[0] = 0.5;
  f[1] = 2;
  f[2] = 3;
  for (size_t i = 3; i < f.size(); ++i) f[i] = double(i % 2) + 1e-3 * double(i);
  return m;
}

// Two tetrahedra meeting at vertex 0 alone, and a third joining their vertices 1 and 4 by an
// edge outside 0's star: 0's lower link has two components, its lower neighbours one group
// joined by edges (so 0 is no join saddle: 1 and 4 meet below it).
Mesh BridgedLink() {
  Mesh m;
  m.points = {0, 0,  0, 1, 0, 0,  0, 1,  0,   0, 0,  1,   -1, 0, 0,  // 0-4
              0, -1, 0, 0, 0, -1, 1, -1, 0.5, 1, -1, -0.5};          // 5-8
  m.tetrahedra = {0, 1, 2, 3, 0, 4, 5, 6, 1, 4, 7, 8};
  m.point_fields.push_back({"height", {10, 1, 2, 3, 1.5, 2.5, 3.5, 0.5, 0.7}});
  return m;
}

std::vector<Case> Cases() {
  std::vector<Case> out;
  const auto add = [&out](std::string name, Mesh m) {
    std::vector<double> s = m.point_fields[0].values;
    out.push_back({std::move(name), std::move(m), std::move(s)});
  };
  add("single", testing::SingleTetrahedron());
  add("lattice", testing::Lattice(9, 8, 7, 12));
  add("two_components", testing::TwoComponents());
  add("non_manifold", testing::NonManifold());
  add("bipyramid", testing::Bipyramid(12, true));
  add("pinched", PinchedWithIsolatedPoint());
  add("wide_saddle", WideSaddle());
  add("bridged_link", BridgedLink());
  Mesh ties = testing::Lattice(7, 6, 5, 3);
  for (double& x : ties.point_fields[0].values) x = std::round(x * 2) / 2;
  add("lattice_ties", std::move(ties));
  return out;
}

std::shared_ptr<const Topology> Build(const Mesh& m, int capacity) {
  return OkValue(Topology::Build(m, OctreeBlocks(m.points, {.bucket_capacity = capacity})));
}

// The tree as sets of input vertices, independent of numbering.
struct Shape {
  std::set<std::pair<SimplexId, int>> nodes;
  std::multiset<std::pair<SimplexId, SimplexId>> arcs;
  std::vector<std::pair<SimplexId, SimplexId>> segmentation;
  bool operator==(const Shape&) const = default;
};

Shape ShapeOf(const TreeResult& r) {
  Shape s;
  for (const TreeNode& n : r.nodes) s.nodes.insert({n.vertex, int(n.type)});
  for (const TreeArc& a : r.arcs)
    s.arcs.insert({r.nodes[a.down_node].vertex, r.nodes[a.up_node].vertex});
  for (int32_t a : r.vertex_arc) {
    s.segmentation.push_back(
        {r.nodes[r.arcs[a].down_node].vertex, r.nodes[r.arcs[a].up_node].vertex});
  }
  return s;
}

Shape ShapeOf(const OracleTree& t) {
  Shape s;
  for (const auto& [v, type] : t.nodes) s.nodes.insert({v, type});
  for (const auto& arc : t.arcs) s.arcs.insert(arc);
  s.segmentation = t.segmentation;
  return s;
}

void PrintTo(const Shape& s, std::ostream* out) {
  *out << "nodes:";
  for (const auto& [v, t] : s.nodes) *out << " " << v << "/" << t;
  *out << " arcs:";
  for (const auto& [d, u] : s.arcs) *out << " " << d << "-" << u;
  *out << " segmentation:";
  for (const auto& [d, u] : s.segmentation) *out << " " << d << "-" << u;
}

// Runs `check(label, structure, context)` on every structure with 1, 2 and 3 consumers; explicit
// with VV (the numbered link scan) and without.
template <class Check>
void OnEveryStructure(const std::shared_ptr<const Topology>& topo, Check&& check) {
  auto explicit_structure = OkValue(ExplicitStructure::Build(topo, {.relations = TreeDeclared()}));
  auto explicit_stars = OkValue(ExplicitStructure::Build(topo, {.relations = {Relation::kVT}}));
  for (int consumers : {1, 2, 3}) {
    const RunContext context{.consumers = consumers};
    const std::string c = " C=" + std::to_string(consumers);
    check("explicit" + c, *explicit_structure, context);
    check("explicit without VV" + c, *explicit_stars, context);
    CompactStructure compact(topo, {.cache_ratio = 0.1, .consumers = consumers});
    check("compact" + c, compact, context);
    auto actopo = OkValue(ActopoStructure::Create(
        topo, {.consumers = consumers, .producers = 1 + consumers % 2, .buffer_ratio = 0.2}));
    check("actopo" + c, *actopo, context);
  }
}

// The mask scans, numbered by VV (ScanNumbered) and as the star meets the link (ScanMasked),
// find as many components on each side as Scan and name a vertex of the right side for each:
// on a lattice whose neighbours lie in other blocks (far apart in id), and around a vertex of 72
// neighbours, more than they take (they decline the centre and the two apexes, Scan's business).
TEST(LinkComponents, MaskScansFindScansComponents) {
  Mesh lattice = testing::Lattice(9, 8, 7, 12);
  const auto far =
      OkValue(Topology::Build(lattice, *LabelBlocks(testing::SliceLabels(lattice, 3))));
  const Mesh wide = WideSaddle();
  for (const auto& [name, topo, scalars, declines] :
       {std::tuple{"far lattice", far, lattice.point_fields[0].values, 0},
        std::tuple{"wide saddle", Build(wide, 8), wide.point_fields[0].values, 3}}) {
    const std::vector<SimplexId> order = VertexOrder(*topo, scalars);
    auto structure = OkValue(ExplicitStructure::Build(topo, {.relations = TreeDeclared()}));
    auto reader = structure->NewReader();
    for (bool by_neighbors : {true, false}) {
      for (LinkComponents::Sides sides :
           {LinkComponents::kLower, LinkComponents::kUpper, LinkComponents::kBothSides}) {
        const std::string scan = std::string(name) +
                                 (by_neighbors ? " ScanNumbered" : " ScanMasked") + " sides " +
                                 std::to_string(int(sides));
        LinkComponents star_scan, mask_scan;
        int declined = 0;
        std::vector<SimplexId> reps;
        for (SimplexId v = 0; v < topo->num_vertices(); ++v) {
          if (!(by_neighbors ? mask_scan.ScanNumbered(reader, v, order, sides)
                             : mask_scan.ScanMasked(reader, v, order, sides))) {
            EXPECT_GT(reader.vertex_neighbors(v).size(), 63u) << scan << " vertex " << v;
            ++declined;
            continue;
          }
          star_scan.Scan(reader, v, order);
          for (bool lower : {true, false}) {
            if (!(sides & (lower ? LinkComponents::kLower : LinkComponents::kUpper))) continue;
            int expected = 0;
            for (size_t i = 0; i < star_scan.size(); ++i) {
              expected += star_scan.below(i) == lower && star_scan.IsRepresentative(i);
            }
            mask_scan.MaskedRepresentatives(lower, reps);
            EXPECT_EQ(int(reps.size()), expected) << scan << " vertex " << v << " lower " << lower;
            for (SimplexId w : reps) {
              EXPECT_EQ(order[w] < order[v], lower) << scan << " vertex " << v;
            }
          }
        }
        EXPECT_EQ(declined, declines) << scan;
      }
    }
  }
}

// ScanByEdges groups each side's neighbours by the mesh edges between them: as many groups as a
// union-find over the tetrahedra's edges makes, a vertex of the right side from each. Around
// BridgedLink's vertex 0 that is one group where the lower link has two components.
TEST(LinkComponents, ScanByEdgesGroupsNeighboursByMeshEdges) {
  Mesh lattice = testing::Lattice(9, 8, 7, 12);
  const auto far =
      OkValue(Topology::Build(lattice, *LabelBlocks(testing::SliceLabels(lattice, 3))));
  const Mesh wide = WideSaddle(), bridged = BridgedLink();
  for (const auto& [name, topo, scalars, declines] :
       {std::tuple{"far lattice", far, lattice.point_fields[0].values, 0},
        std::tuple{"wide saddle", Build(wide, 8), wide.point_fields[0].values, 3},
        std::tuple{"bridged link", Build(bridged, 3), bridged.point_fields[0].values, 0}}) {
    const std::vector<SimplexId> order = VertexOrder(*topo, scalars);
    std::set<std::pair<SimplexId, SimplexId>> edges;
    for (SimplexId t = 0; t < topo->num_tetrahedra(); ++t) {
      const auto tuple = topo->tetrahedron(t);
      for (int i = 0; i < 4; ++i) {
        for (int j = 0; j < 4; ++j) {
          if (i != j) edges.insert({tuple[i], tuple[j]});
        }
      }
    }
    auto structure = OkValue(ExplicitStructure::Build(topo, {.relations = TreeDeclared()}));
    auto reader = structure->NewReader();
    LinkComponents scan;
    std::vector<SimplexId> reps;
    for (bool lower : {true, false}) {
      int declined = 0;
      for (SimplexId v = 0; v < topo->num_vertices(); ++v) {
        const std::string where =
            std::string(name) + " vertex " + std::to_string(v) + (lower ? " lower" : " upper");
        if (!scan.ScanByEdges(reader, v, order,
                              lower ? LinkComponents::kLower : LinkComponents::kUpper)) {
          ++declined;
          continue;
        }
        std::vector<SimplexId> side;
        for (auto it = edges.lower_bound({v, 0}); it != edges.end() && it->first == v; ++it) {
          if ((order[it->second] < order[v]) == lower) side.push_back(it->second);
        }
        UnionFind groups(side.size());
        for (size_t i = 0; i < side.size(); ++i) {
          for (size_t j = 0; j < i; ++j) {
            if (edges.count({side[i], side[j]})) groups.Union(int32_t(i), int32_t(j));
          }
        }
        std::set<int32_t> expected, named;
        for (size_t i = 0; i < side.size(); ++i) expected.insert(groups.Find(int32_t(i)));
        scan.MaskedRepresentatives(lower, reps);
        for (SimplexId w : reps) {
          const auto at = std::find(side.begin(), side.end(), w);
          ASSERT_NE(at, side.end()) << where << ": " << w << " is not on the side";
          named.insert(groups.Find(int32_t(at - side.begin())));
        }
        EXPECT_EQ(reps.size(), expected.size()) << where;
        EXPECT_EQ(named.size(), reps.size()) << where << ": two vertices of one group";
      }
      EXPECT_EQ(declined, declines) << name;
    }
    if (std::string(name) == "bridged link") {
      const SimplexId centre = topo->vertex_internal_id(0);
      LinkComponents star_scan;
      star_scan.Scan(reader, centre, order);
      int lower_components = 0;
      for (size_t i = 0; i < star_scan.size(); ++i) {
        lower_components += star_scan.below(i) && star_scan.IsRepresentative(i);
      }
      EXPECT_EQ(lower_components, 2);
      ASSERT_TRUE(scan.ScanByEdges(reader, centre, order, LinkComponents::kLower));
      scan.MaskedRepresentatives(true, reps);
      EXPECT_EQ(reps.size(), 1u);
    }
  }
}

TEST(MergeTree, EqualsTheBruteForceTreeOnEveryStructure) {
  for (const Case& c : Cases()) {
    for (int capacity : {3, 40}) {
      auto topo = Build(c.mesh, capacity);
      const std::vector<SimplexId> order = VertexOrder(*topo, c.scalars);
      for (TreeType type : {TreeType::kJoin, TreeType::kSplit}) {
        const Shape expected = ShapeOf(testing::BruteForceMergeTree(c.mesh, c.scalars, type));
        OnEveryStructure(
            topo, [&](const std::string& label, auto& structure, const RunContext& context) {
              const TreeResult r = OkValue(RunTree(structure, order, type, context));
              EXPECT_EQ(ShapeOf(r), expected) << c.name << " " << TreeTypeName(type) << " " << label
                                              << " capacity " << capacity;
            });
      }
    }
  }
}

// TTK's numbering (docs/trees-plan.md): NodeIds along the sweep within each component, arcs
// in the order of their down node, SegmentationIds a permutation of each component's ids
// starting at its node offset, and up/downNodeId relative to the component.
TEST(MergeTree, NumbersAsTtkDoes) {
  for (const Case& c : Cases()) {
    auto topo = Build(c.mesh, 40);
    const std::vector<SimplexId> order = VertexOrder(*topo, c.scalars);
    auto structure = OkValue(ExplicitStructure::Build(topo, {.relations = TreeDeclared()}));
    for (TreeType type : {TreeType::kJoin, TreeType::kSplit}) {
      const TreeResult r = OkValue(RunTree(*structure, order, type, {}));
      SCOPED_TRACE(c.name + " " + std::string(TreeTypeName(type)));
      ASSERT_GE(r.component_node_begin.size(), 2u);
      EXPECT_EQ(r.component_node_begin.back(), int32_t(r.nodes.size()));
      const auto rank = [&](int32_t node) {
        const SimplexId o = order[topo->vertex_internal_id(r.nodes[node].vertex)];
        return type == TreeType::kJoin ? o : -o;
      };
      for (size_t k = 0; k + 1 < r.component_node_begin.size(); ++k) {
        const int32_t begin = r.component_node_begin[k], end = r.component_node_begin[k + 1];
        for (int32_t i = begin + 1; i < end; ++i) EXPECT_LT(rank(i - 1), rank(i));
        std::vector<int32_t> ids;
        for (const TreeArc& a : r.arcs) {
          if (a.down_node >= begin && a.down_node < end) ids.push_back(a.segmentation_id - begin);
        }
        std::sort(ids.begin(), ids.end());
        for (size_t i = 0; i < ids.size(); ++i) EXPECT_EQ(ids[i], int32_t(i));
      }
      for (size_t i = 1; i < r.arcs.size(); ++i) {
        EXPECT_LT(std::pair(r.arcs[i - 1].down_node, r.arcs[i - 1].up_node),
                  std::pair(r.arcs[i].down_node, r.arcs[i].up_node));
      }
      int64_t regular = 0;
      for (const TreeArc& a : r.arcs) regular += a.region_size;
      EXPECT_EQ(regular + int64_t(r.nodes.size()), int64_t(c.mesh.num_vertices()));
    }
  }
}

// Properties of the join tree: minima are leaves with one arc up, saddles have two or more arcs
// down; the split tree mirrors it.
TEST(MergeTree, NodeDegreesFollowTheirTypes) {
  const Mesh m = testing::Lattice(9, 8, 7, 12);
  auto topo = Build(m, 40);
  const std::vector<SimplexId> order = VertexOrder(*topo, m.point_fields[0].values);
  auto structure = OkValue(ExplicitStructure::Build(topo, {.relations = TreeDeclared()}));
  for (TreeType type : {TreeType::kJoin, TreeType::kSplit}) {
    const TreeResult r = OkValue(RunTree(*structure, order, type, {}));
    std::vector<int> up(r.nodes.size()), down(r.nodes.size());
    for (const TreeArc& a : r.arcs) {
      ++up[a.down_node];
      ++down[a.up_node];
    }
    const CriticalType leaf =
        type == TreeType::kJoin ? CriticalType::kMinimum : CriticalType::kMaximum;
    const CriticalType saddle =
        type == TreeType::kJoin ? CriticalType::kSaddle1 : CriticalType::kSaddle2;
    int leaves = 0;
    for (size_t i = 0; i < r.nodes.size(); ++i) {
      if (r.nodes[i].type == leaf) {
        ++leaves;
        EXPECT_EQ(up[i], 1);
        EXPECT_EQ(down[i], 0);
      }
      if (r.nodes[i].type == saddle) {
        EXPECT_EQ(up[i], 1);
        EXPECT_EQ(down[i], 2);
      }
    }
    EXPECT_GT(leaves, 1) << TreeTypeName(type);
  }
}

// A join tree arc's vertices with everything below it are a component of a sublevel set, so
// connected over the edges (and dually for the split tree).
TEST(MergeTree, ArcsWithTheirSubtreesAreConnected) {
  const Mesh m = testing::Lattice(9, 8, 7, 12);
  auto topo = Build(m, 40);
  const std::vector<SimplexId> order = VertexOrder(*topo, m.point_fields[0].values);
  auto structure = OkValue(ExplicitStructure::Build(topo, {.relations = TreeDeclared()}));
  std::vector<std::set<SimplexId>> adjacent(size_t(m.num_vertices()));
  for (SimplexId t = 0; t < m.num_tetrahedra(); ++t) {
    for (int i = 0; i < 4; ++i) {
      for (int j = 0; j < 4; ++j) adjacent[m.tetrahedra[4 * t + i]].insert(m.tetrahedra[4 * t + j]);
    }
  }
  for (TreeType type : {TreeType::kJoin, TreeType::kSplit}) {
    const TreeResult r = OkValue(RunTree(*structure, order, type, {}));
    std::vector<int32_t> arc_of_down(r.nodes.size(), -1);
    for (size_t a = 0; a < r.arcs.size(); ++a) arc_of_down[r.arcs[a].down_node] = int32_t(a);
    for (size_t a = 0; a < r.arcs.size(); ++a) {
      // Members: the vertices whose arc climbs to arc a, and the nodes below it.
      std::set<SimplexId> members;
      for (SimplexId v = 0; v < m.num_vertices(); ++v) {
        for (int32_t b = r.vertex_arc[v]; b >= 0;) {
          if (b == int32_t(a)) members.insert(v);
          const int32_t next = arc_of_down[r.arcs[b].up_node];
          b = next == b ? -1 : next;
        }
      }
      members.insert(r.nodes[r.arcs[a].down_node].vertex);
      std::set<SimplexId> reached = {*members.begin()};
      std::vector<SimplexId> stack = {*members.begin()};
      while (!stack.empty()) {
        const SimplexId v = stack.back();
        stack.pop_back();
        for (SimplexId w : adjacent[v]) {
          if (members.contains(w) && reached.insert(w).second) stack.push_back(w);
        }
      }
      EXPECT_EQ(reached.size(), members.size()) << TreeTypeName(type) << " arc " << a;
    }
  }
}

// The join tree's branches by the elder rule (at each saddle the branch born lowest goes on,
// the others end there) are the persistence diagram's finite minimum-saddle pairs. (The
// non-manifold meshes are left out: there the diagram pairs cells, not the link's components.)
TEST(MergeTree, JoinTreeBranchesAreTheDiagramsMinimumSaddlePairs) {
  for (const Case& c : Cases()) {
    if (c.name == "pinched" || c.name == "non_manifold") continue;  // the diagram's are cells'
    SCOPED_TRACE(c.name);
    auto topo = Build(c.mesh, 40);
    const std::vector<SimplexId> order = VertexOrder(*topo, c.scalars);
    auto structure = OkValue(ExplicitStructure::Build(topo, {}));
    const TreeResult join = OkValue(RunTree(*structure, order, TreeType::kJoin, {}));
    // NodeIds follow the order within a component: children come before their parent.
    std::vector<SimplexId> birth(join.nodes.size(), -1);
    const auto rank = [&](SimplexId input) { return order[topo->vertex_internal_id(input)]; };
    std::set<std::pair<SimplexId, SimplexId>> tree_pairs, diagram_pairs;
    std::vector<std::vector<int32_t>> children(join.nodes.size());
    for (const TreeArc& a : join.arcs) {
      if (a.down_node != a.up_node) children[a.up_node].push_back(a.down_node);
    }
    for (size_t n = 0; n < join.nodes.size(); ++n) {
      if (children[n].empty()) {
        birth[n] = join.nodes[n].vertex;
        continue;
      }
      std::vector<SimplexId> births;
      for (int32_t child : children[n]) births.push_back(birth[child]);
      std::sort(births.begin(), births.end(),
                [&](SimplexId a, SimplexId b) { return rank(a) < rank(b); });
      birth[n] = births[0];
      for (size_t k = 1; k < births.size(); ++k)
        tree_pairs.insert({births[k], join.nodes[n].vertex});
    }
    const PersistenceDiagramResult diagram =
        OkValue(RunPersistenceDiagram(*structure, order, c.scalars, {}));
    for (const PersistencePair& p : diagram.pairs) {
      if (p.type == 0 && p.finite()) diagram_pairs.insert({p.birth, p.death});
    }
    EXPECT_EQ(tree_pairs, diagram_pairs);
  }
}

// The contour tree: identical on every structure and consumer count; its nodes are the join
// and split trees' nodes; every other vertex lies strictly between its arc's two ends. (Its
// regions need not be connected over the edges: FTM gives a vertex to the first arc peeled
// off either tree that holds it; the fidelity tests compare them with TTK's.)
TEST(ContourTree, CombinesTheJoinAndSplitTrees) {
  for (const Case& c : Cases()) {
    auto topo = Build(c.mesh, 3);
    const std::vector<SimplexId> order = VertexOrder(*topo, c.scalars);
    auto structure = OkValue(ExplicitStructure::Build(topo, {.relations = TreeDeclared()}));
    const TreeResult contour = OkValue(RunTree(*structure, order, TreeType::kContour, {}));
    SCOPED_TRACE(c.name);
    std::set<SimplexId> expected_nodes, nodes;
    for (TreeType type : {TreeType::kJoin, TreeType::kSplit}) {
      for (const TreeNode& n : OkValue(RunTree(*structure, order, type, {})).nodes) {
        expected_nodes.insert(n.vertex);
      }
    }
    for (const TreeNode& n : contour.nodes) nodes.insert(n.vertex);
    EXPECT_EQ(nodes, expected_nodes);
    const auto rank = [&](SimplexId input) { return order[topo->vertex_internal_id(input)]; };
    for (SimplexId v = 0; v < c.mesh.num_vertices(); ++v) {
      const TreeArc& a = contour.arcs[contour.vertex_arc[v]];
      const SimplexId down = contour.nodes[a.down_node].vertex;
      const SimplexId up = contour.nodes[a.up_node].vertex;
      if (nodes.contains(v)) {
        EXPECT_TRUE(v == down || v == up) << v;
        continue;
      }
      EXPECT_LT(rank(down), rank(v)) << v;
      EXPECT_LT(rank(v), rank(up)) << v;
    }
    const Shape shape = ShapeOf(contour);
    OnEveryStructure(topo, [&](const std::string& label, auto& s, const RunContext& context) {
      const TreeResult r = OkValue(RunTree(s, order, TreeType::kContour, context));
      EXPECT_EQ(ShapeOf(r), shape) << label;
      EXPECT_EQ(r.SegmentationDigest(), contour.SegmentationDigest()) << label;
    });
  }
}

}  // namespace
}  // namespace actopo
