#include "server/algorithms/critical_points.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <numeric>
#include <optional>
#include <random>
#include <set>

#include "gtest/gtest.h"
#include "server/algorithms/discrete_gradient.h"
#include "server/algorithms/link_components.h"
#include "server/algorithms/testing/gradient_checks.h"
#include "server/algorithms/vertex_order.h"
#include "server/core/actopo_structure.h"
#include "server/core/compact_structure.h"
#include "server/core/explicit_structure.h"
#include "server/core/partition.h"
#include "server/core/testing/oracle.h"
#include "server/core/testing/status.h"
#include "server/core/testing/test_meshes.h"

namespace actopo {
namespace {

std::shared_ptr<const Topology> Build(const Mesh& m, int capacity) {
  return OkValue(Topology::Build(m, OctreeBlocks(m.points, {.bucket_capacity = capacity})));
}

// A field with many exact ties, to exercise the (scalar, id) tie-break.
std::vector<double> Quantised(const Mesh& m) {
  std::vector<double> q = m.point_fields[0].values;
  for (double& x : q) x = std::round(x * 2) / 2;
  return q;
}

struct Fixture {
  std::shared_ptr<const Topology> topo;
  std::vector<SimplexId> order;
};

std::vector<Fixture> Fixtures() {
  std::vector<Fixture> out;
  const Mesh lattice = testing::Lattice(9, 8, 7, 12);
  const Mesh two = testing::TwoComponents();
  for (const auto& [mesh, scalars] :
       {std::pair{lattice, lattice.point_fields[0].values}, std::pair{lattice, Quantised(lattice)},
        std::pair{two, two.point_fields[0].values}}) {
    auto topo = Build(mesh, 17);
    out.push_back({topo, VertexOrder(*topo, scalars)});
  }
  return out;
}

TEST(VertexOrder, BreaksTiesByInputId) {
  const Mesh m = testing::Lattice(3, 3, 3, 5);
  auto topo = Build(m, 4);
  const std::vector<double> flat(m.num_vertices(), 1.0);
  const std::vector<SimplexId> order = VertexOrder(*topo, flat);
  for (SimplexId input = 0; input < m.num_vertices(); ++input) {
    EXPECT_EQ(order[topo->vertex_internal_id(input)], input);
  }
}

TEST(CriticalPoints, IdenticalOnEveryStructureAndMode) {
  for (const Fixture& f : Fixtures()) {
    auto explicit_structure =
        OkValue(ExplicitStructure::Build(f.topo, {.relations = CriticalPointsDeclared()}));
    const CriticalPointsResult reference =
        OkValue(RunCriticalPoints(*explicit_structure, f.order, {}, {}));
    ASSERT_FALSE(reference.points.empty());
    const std::string digest = reference.VerticesDigest();
    for (int consumers : {1, 2}) {
      EXPECT_EQ(RunCriticalPoints(*explicit_structure, f.order, {}, {.consumers = consumers})
                    ->VerticesDigest(),
                digest);
      CompactStructure compact(f.topo, {.cache_ratio = 0.1, .consumers = consumers});
      EXPECT_EQ(RunCriticalPoints(compact, f.order, {}, {.consumers = consumers})->VerticesDigest(),
                digest);
      for (Prefetch p : {Prefetch::kLinear, Prefetch::kSpatial, Prefetch::kAdaptive}) {
        for (Precompute q : {Precompute::kRequested, Precompute::kDeclared}) {
          auto actopo =
              OkValue(ActopoStructure::Create(f.topo, {.consumers = consumers,
                                                       .producers = 2,
                                                       .buffer_ratio = 0.1,
                                                       .prefetch = p,
                                                       .precompute = q,
                                                       .declared = CriticalPointsDeclared()}));
          EXPECT_EQ(
              RunCriticalPoints(*actopo, f.order, {}, {.consumers = consumers})->VerticesDigest(),
              digest)
              << PrefetchName(p) << " " << PrecomputeName(q) << " C=" << consumers;
        }
      }
    }
  }
}

TEST(CriticalPoints, BoundaryRuleOnlyAddsBoundarySaddles) {
  for (const Fixture& f : Fixtures()) {
    auto s = OkValue(ExplicitStructure::Build(f.topo, {.relations = CriticalPointsDeclared()}));
    const auto ttk = OkValue(RunCriticalPoints(*s, f.order, {}, {}));
    const auto none =
        OkValue(RunCriticalPoints(*s, f.order, {.boundary_rule = BoundaryRule::kNone}, {}));
    // Extrema and interior points agree; with the rule, extra saddles all lie on the boundary.
    EXPECT_EQ(ttk.counts[int(CriticalType::kMinimum)], none.counts[int(CriticalType::kMinimum)]);
    EXPECT_EQ(ttk.counts[int(CriticalType::kMaximum)], none.counts[int(CriticalType::kMaximum)]);
    size_t j = 0;
    for (const CriticalPoint& p : ttk.points) {
      if (j < none.points.size() && none.points[j].vertex == p.vertex) {
        EXPECT_EQ(none.points[j].type, p.type);
        ++j;
      } else {
        EXPECT_TRUE(p.on_boundary) << "vertex " << p.vertex;
        EXPECT_TRUE(p.type == CriticalType::kSaddle1 || p.type == CriticalType::kSaddle2);
      }
    }
    EXPECT_EQ(j, none.points.size());
  }
}

// TTK's boundary rule by its definition: a regular boundary vertex whose boundary neighbours
// (the oracle's VV and VB) all lie above it is a 1-saddle, all below a 2-saddle. Classify reads
// VB only for neighbours that are not ends of the vertex's own boundary triangles, and only
// until both sides are seen; the points must be the same on every structure.
TEST(CriticalPoints, BoundaryRuleEqualsItsDefinitionOverTheOraclesVertexBoundary) {
  std::vector<Fixture> fixtures = Fixtures();
  for (bool closed : {true, false}) {  // a centre with 81 or 82 neighbours: the sorted keys
    const Mesh m = testing::Bipyramid(80, closed);
    auto topo = Build(m, 10);
    fixtures.push_back({topo, VertexOrder(*topo, m.point_fields[0].values)});
  }
  int rule_saddles = 0;
  for (const Fixture& f : fixtures) {
    const testing::RelationOracle oracle(*f.topo);
    const auto& vb = oracle.rows(Relation::kVB);
    const auto& vv = oracle.rows(Relation::kVV);
    auto explicit_structure =
        OkValue(ExplicitStructure::Build(f.topo, {.relations = CriticalPointsDeclared()}));
    const auto none = OkValue(RunCriticalPoints(*explicit_structure, f.order,
                                                {.boundary_rule = BoundaryRule::kNone}, {}));
    std::map<SimplexId, CriticalType> expected;  // by input id
    for (const CriticalPoint& p : none.points) expected[p.vertex] = p.type;
    for (SimplexId v = 0; v < f.topo->num_vertices(); ++v) {
      const SimplexId input = f.topo->vertex_input_id(v);
      if (expected.count(input) || vb[v][0] == 0) continue;  // critical anyway, or interior
      bool lower = false, upper = false;
      for (SimplexId w : vv[v]) {
        if (vb[w][0] != 0) (f.order[w] < f.order[v] ? lower : upper) = true;
      }
      if (upper && !lower) expected[input] = CriticalType::kSaddle1;
      if (lower && !upper) expected[input] = CriticalType::kSaddle2;
      rule_saddles += upper != lower;
    }
    CompactStructure compact(f.topo, {.cache_ratio = 0.1});
    auto actopo = OkValue(ActopoStructure::Create(
        f.topo, {.precompute = Precompute::kDeclared, .declared = CriticalPointsSwept()}));
    const auto check = [&](const CriticalPointsResult& r, const char* structure) {
      std::map<SimplexId, CriticalType> found;
      for (const CriticalPoint& p : r.points) found[p.vertex] = p.type;
      EXPECT_EQ(found, expected) << structure;
    };
    check(OkValue(RunCriticalPoints(*explicit_structure, f.order, {}, {})), "explicit");
    check(OkValue(RunCriticalPoints(compact, f.order, {}, {})), "compact");
    check(OkValue(RunCriticalPoints(*actopo, f.order, {}, {})), "actopo");
  }
  EXPECT_GT(rule_saddles, 0);  // else the rule would not be seen at work
}

// A vertex's own boundary flag comes from the link edges Classify counts (LinkEdgeCounter,
// whose sorted keys take over past 64 link vertices): every reported point's flag must be the
// oracle's VB, on every structure. The bipyramid's centre has 81 or 82 neighbours and is the
// minimum of the distance to it.
TEST(CriticalPoints, OnBoundaryIsTheOraclesVertexBoundary) {
  std::vector<Fixture> fixtures = Fixtures();
  for (bool closed : {true, false}) {
    const Mesh m = testing::Bipyramid(80, closed);
    auto topo = Build(m, 10);
    fixtures.push_back({topo, VertexOrder(*topo, m.point_fields[0].values)});
  }
  for (const Fixture& f : fixtures) {
    const testing::RelationOracle oracle(*f.topo);
    const auto& vb = oracle.rows(Relation::kVB);
    auto explicit_structure =
        OkValue(ExplicitStructure::Build(f.topo, {.relations = CriticalPointsDeclared()}));
    CompactStructure compact(f.topo, {.cache_ratio = 0.1});
    auto actopo = OkValue(ActopoStructure::Create(
        f.topo, {.precompute = Precompute::kDeclared, .declared = CriticalPointsSwept()}));
    const auto check = [&](const CriticalPointsResult& r, const char* structure) {
      ASSERT_FALSE(r.points.empty());
      for (const CriticalPoint& p : r.points) {
        EXPECT_EQ(p.on_boundary, vb[f.topo->vertex_internal_id(p.vertex)][0] != 0)
            << structure << ": input vertex " << p.vertex;
      }
    };
    check(OkValue(RunCriticalPoints(*explicit_structure, f.order, {}, {})), "explicit");
    check(OkValue(RunCriticalPoints(compact, f.order, {}, {})), "compact");
    check(OkValue(RunCriticalPoints(*actopo, f.order, {}, {})), "actopo");
  }
  // The centre is the open bipyramid's minimum, on the boundary.
  const Fixture& open = fixtures.back();
  auto s = OkValue(ExplicitStructure::Build(open.topo, {.relations = CriticalPointsDeclared()}));
  const CriticalPointsResult r = OkValue(RunCriticalPoints(*s, open.order, {}, {}));
  ASSERT_FALSE(r.points.empty());
  EXPECT_EQ(r.points[0].vertex, 0);
  EXPECT_EQ(r.points[0].type, CriticalType::kMinimum);
  EXPECT_TRUE(r.points[0].on_boundary);
}

// The mask scan's boundary: for every vertex of links within 63 vertices, the ends of the link
// edges that one star tetrahedron alone holds, counted here over the star, and none exactly when
// the oracle's VB says the vertex is inside (a non-manifold mesh among them: a link edge three
// tetrahedra hold is inside, as in LinkEdgeCounter).
TEST(CriticalPoints, MaskedBoundaryEndsAreTheLinkEdgesMetOnce) {
  std::vector<Fixture> fixtures = Fixtures();
  const Mesh odd = testing::NonManifold();
  auto odd_topo = Build(odd, 4);
  fixtures.push_back({odd_topo, VertexOrder(*odd_topo, odd.point_fields[0].values)});
  int ends_seen = 0;
  for (const Fixture& f : fixtures) {
    const testing::RelationOracle oracle(*f.topo);
    const auto& vb = oracle.rows(Relation::kVB);
    const auto& vt = oracle.rows(Relation::kVT);
    auto structure =
        OkValue(ExplicitStructure::Build(f.topo, {.relations = CriticalPointsDeclared()}));
    auto reader = structure->NewReader();
    LinkComponents scan;
    for (SimplexId v = 0; v < f.topo->num_vertices(); ++v) {
      ASSERT_TRUE(scan.ScanMasked(reader, v, f.order, LinkComponents::kBothSides)) << v;
      std::map<std::pair<SimplexId, SimplexId>, int> edges;
      for (SimplexId t : vt[v]) {
        std::vector<SimplexId> other;
        for (SimplexId w : f.topo->tetrahedron(t)) {
          if (w != v) other.push_back(w);
        }
        std::sort(other.begin(), other.end());
        ++edges[{other[0], other[1]}], ++edges[{other[0], other[2]}], ++edges[{other[1], other[2]}];
      }
      std::set<SimplexId> expected, found;
      for (const auto& [edge, count] : edges) {
        if (count == 1) expected.insert({edge.first, edge.second});
      }
      const uint64_t ends = scan.MaskedBoundaryEnds();
      for (int i = 0; i < 64; ++i) {
        if ((ends >> i) & 1) found.insert(scan.MaskedVertex(i));
      }
      EXPECT_EQ(found, expected) << "vertex " << v;
      EXPECT_EQ(ends != 0, vb[v][0] != 0) << "vertex " << v;
      ends_seen += !found.empty();
    }
  }
  EXPECT_GT(ends_seen, 0);
}

TEST(CriticalPoints, MinimaAgreeWithTheGradient) {
  for (const Fixture& f : Fixtures()) {
    auto s = OkValue(ExplicitStructure::Build(f.topo, {}));
    const auto points =
        OkValue(RunCriticalPoints(*s, f.order, {.boundary_rule = BoundaryRule::kNone}, {}));
    const auto gradient = OkValue(RunDiscreteGradient(*s, f.order, {}, GradientArrays::kAll));
    EXPECT_EQ(points.counts[int(CriticalType::kMinimum)], gradient.critical_cells[0]);
  }
}

// Robins et al.'s ProcessLowerStars as the paper states it, for the tests below: each cell of a
// lower star keyed by its other vertices' orders (descending, padded with -1), both queues as
// ordered sets of (key, cell), faces through the explicit structure's FE and TF. The production
// pairing numbers edges, ranks small keys and finds faces by search; this has none of that.
struct ReferenceGradient {
  std::array<std::vector<SimplexId>, 4> up, down;  // as GradientField; -1 when none
  std::array<std::vector<SimplexId>, 4> critical;  // ascending ids
};

ReferenceGradient PairLowerStarsByDefinition(ExplicitStructure& structure,
                                             std::span<const SimplexId> order) {
  const Topology& topo = structure.topology();
  auto reader = structure.NewReader();
  ReferenceGradient g;
  for (int d = 0; d < 4; ++d) {
    g.up[d].assign(size_t(topo.num_simplices(d)), -1);
    g.down[d].assign(size_t(topo.num_simplices(d)), -1);
  }
  using Key = std::array<SimplexId, 3>;
  using Cell = std::pair<int, SimplexId>;  // (dimension, id)
  for (SimplexId x = 0; x < topo.num_vertices(); ++x) {
    std::map<Cell, Key> star;  // x's lower star with the keys
    const auto add_if_lower = [&](int d, SimplexId c) {
      SimplexId ids[4];
      CellVertices(topo, d, c, ids);
      Key key{-1, -1, -1};
      int n = 0;
      for (int i = 0; i <= d; ++i) {
        if (ids[i] == x) continue;
        if (order[ids[i]] > order[x]) return;
        key[n++] = order[ids[i]];
      }
      // Descending; the padding, below every order, goes last.
      if (key[0] < key[1]) std::swap(key[0], key[1]);
      if (key[1] < key[2]) std::swap(key[1], key[2]);
      if (key[0] < key[1]) std::swap(key[0], key[1]);
      star[{d, c}] = key;
    };
    for (SimplexId e : reader.vertex_edges(x)) add_if_lower(1, e);
    for (SimplexId f : reader.vertex_triangles(x)) add_if_lower(2, f);
    for (SimplexId t : reader.vertex_star(x)) add_if_lower(3, t);
    if (star.empty()) {
      g.critical[0].push_back(x);
      continue;
    }
    const auto faces = [&](Cell c) {  // those in the star: the ones that contain x
      std::vector<Cell> out;
      const auto all =
          c.first == 2 ? reader.triangle_edges(c.second) : reader.tetrahedron_triangles(c.second);
      for (SimplexId f : all) {
        if (star.count({c.first - 1, f})) out.push_back({c.first - 1, f});
      }
      return out;
    };
    std::map<Cell, std::vector<Cell>> cofacets;
    for (const auto& [c, key] : star) {
      if (c.first < 2) continue;
      for (Cell f : faces(c)) cofacets[f].push_back(c);
    }
    std::set<Cell> paired;
    const auto unpaired_faces = [&](Cell c) {
      std::vector<Cell> out;
      for (Cell f : faces(c)) {
        if (!paired.count(f)) out.push_back(f);
      }
      return out;
    };
    std::set<std::pair<Key, Cell>> pq_zero, pq_one;
    const auto push_cofacets = [&](Cell c) {
      for (Cell q : cofacets[c]) {
        if (unpaired_faces(q).size() == 1) pq_one.insert({star[q], q});
      }
    };
    const auto pair = [&](Cell lower, Cell higher) {
      g.up[lower.first][lower.second] = higher.second;
      g.down[higher.first][higher.second] = lower.second;
      paired.insert(lower);
      paired.insert(higher);
    };
    std::optional<std::pair<Key, Cell>> delta;
    for (const auto& [c, key] : star) {
      if (c.first == 1 && (!delta || key < delta->first)) delta = {key, c};
    }
    pair({0, x}, delta->second);
    for (const auto& [c, key] : star) {
      if (c.first == 1 && c != delta->second) pq_zero.insert({key, c});
    }
    push_cofacets(delta->second);
    while (!pq_one.empty() || !pq_zero.empty()) {
      while (!pq_one.empty()) {
        const Cell alpha = pq_one.begin()->second;
        pq_one.erase(pq_one.begin());
        const std::vector<Cell> unpaired = unpaired_faces(alpha);
        EXPECT_LE(unpaired.size(), 1u);
        if (unpaired.empty()) {
          pq_zero.insert({star[alpha], alpha});
        } else {
          pair(unpaired[0], alpha);
          push_cofacets(alpha);
          push_cofacets(unpaired[0]);
        }
      }
      while (!pq_zero.empty() && paired.count(pq_zero.begin()->second)) {
        pq_zero.erase(pq_zero.begin());
      }
      if (!pq_zero.empty()) {
        const Cell gamma = pq_zero.begin()->second;
        pq_zero.erase(pq_zero.begin());
        paired.insert(gamma);
        g.critical[gamma.first].push_back(gamma.second);
        push_cofacets(gamma);
      }
    }
  }
  for (auto& cells : g.critical) std::sort(cells.begin(), cells.end());
  return g;
}

void ExpectEqualsReference(const DiscreteGradientResult& r, const ReferenceGradient& want,
                           const std::string& label) {
  for (int d = 0; d < 4; ++d) {
    if (d < 3) {
      EXPECT_TRUE(std::equal(r.gradient.up[d].begin(), r.gradient.up[d].end(), want.up[d].begin(),
                             want.up[d].end()))
          << label << ": up[" << d << "]";
    }
    if (d > 0) {
      EXPECT_TRUE(std::equal(r.gradient.down[d].begin(), r.gradient.down[d].end(),
                             want.down[d].begin(), want.down[d].end()))
          << label << ": down[" << d << "]";
    }
    EXPECT_EQ(r.critical[d], want.critical[d]) << label << ": critical " << d;
  }
}

// Both ways of reading a lower star (VE, VF and VT on explicit; VT alone and the static lookups
// when an update pairs stars again on compact) against the pairing by definition. The orders
// include a shuffled one, and the bipyramid's centre last, whose lower star holds 80 ring
// vertices: hundreds of cells, over several words of the pairing's rank sets.
TEST(DiscreteGradient, EqualsTheLowerStarPairingByDefinition) {
  struct Case {
    std::shared_ptr<const Topology> topo;
    std::vector<SimplexId> order;
    std::string label;
  };
  std::vector<Case> cases;
  const auto reversed = [](std::vector<SimplexId> order) {
    for (SimplexId& o : order) o = SimplexId(order.size()) - 1 - o;
    return order;
  };
  int index = 0;
  for (const Fixture& f : Fixtures()) {
    const std::string name = "fixture " + std::to_string(index++);
    cases.push_back({f.topo, f.order, name});
    std::vector<SimplexId> shuffled(f.order.size());
    std::iota(shuffled.begin(), shuffled.end(), 0);
    std::shuffle(shuffled.begin(), shuffled.end(), std::mt19937(index));
    cases.push_back({f.topo, shuffled, name + ", shuffled"});
  }
  for (bool closed : {true, false}) {
    const Mesh m = testing::Bipyramid(80, closed);
    auto topo = Build(m, 10);
    const std::vector<SimplexId> order = VertexOrder(*topo, m.point_fields[0].values);
    const std::string name = closed ? "closed bipyramid" : "open bipyramid";
    cases.push_back({topo, order, name});
    cases.push_back({topo, reversed(order), name + ", centre last"});
  }
  for (const Case& c : cases) {
    auto explicit_structure = OkValue(ExplicitStructure::Build(c.topo, {}));
    const ReferenceGradient want = PairLowerStarsByDefinition(*explicit_structure, c.order);
    ExpectEqualsReference(
        OkValue(RunDiscreteGradient(*explicit_structure, c.order, {}, GradientArrays::kAll)), want,
        c.label + ", explicit");
    // Paired again from the gradient of another order, every vertex reordered.
    CompactStructure compact(c.topo, {.cache_ratio = 0.1, .consumers = 2});
    std::vector<SimplexId> every(c.order.size());
    std::iota(every.begin(), every.end(), 0);
    const std::vector<SimplexId> other = reversed(c.order);
    ExpectEqualsReference(
        OkValue(UpdateDiscreteGradient(
            compact, OkValue(RunDiscreteGradient(compact, other, {}, GradientArrays::kAll)),
            c.order, every, {.consumers = 2})),
        want, c.label + ", compact update");
  }
}

TEST(DiscreteGradient, ValidAndIdenticalOnEveryStructureAndMode) {
  for (const Fixture& f : Fixtures()) {
    auto explicit_structure = OkValue(ExplicitStructure::Build(f.topo, {}));
    const DiscreteGradientResult reference =
        OkValue(RunDiscreteGradient(*explicit_structure, f.order, {}, GradientArrays::kAll));
    testing::ExpectValidGradient(reference, *explicit_structure);
    const std::string pairs = reference.PairsDigest(*f.topo);
    const std::string critical = reference.CriticalCellsDigest(*f.topo);
    auto check = [&](const DiscreteGradientResult& r, const std::string& label) {
      EXPECT_EQ(r.critical_cells, reference.critical_cells) << label;
      EXPECT_EQ(r.PairsDigest(*f.topo), pairs) << label;
      EXPECT_EQ(r.CriticalCellsDigest(*f.topo), critical) << label;
    };
    // The persistence arrays only: the same pairs, read from down[3] for d = 2.
    const auto kept = OkValue(
        RunDiscreteGradient(*explicit_structure, f.order, {}, GradientArrays::kPersistence));
    EXPECT_TRUE(kept.gradient.up[2].empty());
    check(kept, "explicit, persistence arrays");
    for (int consumers : {1, 2}) {
      CompactStructure compact(f.topo, {.cache_ratio = 0.1, .consumers = consumers});
      check(OkValue(RunDiscreteGradient(compact, f.order, {.consumers = consumers},
                                        GradientArrays::kAll)),
            "compact");
      for (Prefetch p : {Prefetch::kLinear, Prefetch::kSpatial, Prefetch::kAdaptive}) {
        auto actopo =
            OkValue(ActopoStructure::Create(f.topo, {.consumers = consumers,
                                                     .producers = 3,
                                                     .buffer_ratio = 0.05,
                                                     .prefetch = p,
                                                     .precompute = Precompute::kDeclared,
                                                     .declared = DiscreteGradientDeclared()}));
        check(OkValue(RunDiscreteGradient(*actopo, f.order, {.consumers = consumers},
                                          GradientArrays::kAll)),
              std::string(PrefetchName(p)));
      }
    }
  }
}

}  // namespace
}  // namespace actopo
