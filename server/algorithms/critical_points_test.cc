#include "server/algorithms/critical_points.h"

#include <cmath>
#include <map>

#include "gtest/gtest.h"
#include "server/algorithms/discrete_gradient.h"
#include "server/algorithms/testing/gradient_checks.h"
#include "server/algorithms/vertex_order.h"
#include "server/core/actopo_structure.h"
#include "server/core/compact_structure.h"
#include "server/core/explicit_structure.h"
#include "server/core/partition.h"
#include "server/core/testing/oracle.h"
#include "server/core/testing/test_meshes.h"

namespace actopo {
namespace {

std::shared_ptr<const Topology> Build(const Mesh& m, int capacity) {
  return *Topology::Build(m, OctreeBlocks(m.points, {.bucket_capacity = capacity}));
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
        *ExplicitStructure::Build(f.topo, {.relations = CriticalPointsDeclared()});
    const CriticalPointsResult reference = *RunCriticalPoints(*explicit_structure, f.order, {}, {});
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
          auto actopo = *ActopoStructure::Create(f.topo, {.consumers = consumers,
                                                          .producers = 2,
                                                          .buffer_ratio = 0.1,
                                                          .prefetch = p,
                                                          .precompute = q,
                                                          .declared = CriticalPointsDeclared()});
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
    auto s = *ExplicitStructure::Build(f.topo, {.relations = CriticalPointsDeclared()});
    const auto ttk = *RunCriticalPoints(*s, f.order, {}, {});
    const auto none = *RunCriticalPoints(*s, f.order, {.boundary_rule = BoundaryRule::kNone}, {});
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
        *ExplicitStructure::Build(f.topo, {.relations = CriticalPointsDeclared()});
    const auto none = *RunCriticalPoints(*explicit_structure, f.order,
                                         {.boundary_rule = BoundaryRule::kNone}, {});
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
    auto actopo = *ActopoStructure::Create(
        f.topo, {.precompute = Precompute::kDeclared, .declared = CriticalPointsSwept()});
    const auto check = [&](const CriticalPointsResult& r, const char* structure) {
      std::map<SimplexId, CriticalType> found;
      for (const CriticalPoint& p : r.points) found[p.vertex] = p.type;
      EXPECT_EQ(found, expected) << structure;
    };
    check(*RunCriticalPoints(*explicit_structure, f.order, {}, {}), "explicit");
    check(*RunCriticalPoints(compact, f.order, {}, {}), "compact");
    check(*RunCriticalPoints(*actopo, f.order, {}, {}), "actopo");
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
        *ExplicitStructure::Build(f.topo, {.relations = CriticalPointsDeclared()});
    CompactStructure compact(f.topo, {.cache_ratio = 0.1});
    auto actopo = *ActopoStructure::Create(
        f.topo, {.precompute = Precompute::kDeclared, .declared = CriticalPointsSwept()});
    const auto check = [&](const CriticalPointsResult& r, const char* structure) {
      ASSERT_FALSE(r.points.empty());
      for (const CriticalPoint& p : r.points) {
        EXPECT_EQ(p.on_boundary, vb[f.topo->vertex_internal_id(p.vertex)][0] != 0)
            << structure << ": input vertex " << p.vertex;
      }
    };
    check(*RunCriticalPoints(*explicit_structure, f.order, {}, {}), "explicit");
    check(*RunCriticalPoints(compact, f.order, {}, {}), "compact");
    check(*RunCriticalPoints(*actopo, f.order, {}, {}), "actopo");
  }
  // The centre is the open bipyramid's minimum, on the boundary.
  const Fixture& open = fixtures.back();
  auto s = *ExplicitStructure::Build(open.topo, {.relations = CriticalPointsDeclared()});
  const CriticalPointsResult r = *RunCriticalPoints(*s, open.order, {}, {});
  ASSERT_FALSE(r.points.empty());
  EXPECT_EQ(r.points[0].vertex, 0);
  EXPECT_EQ(r.points[0].type, CriticalType::kMinimum);
  EXPECT_TRUE(r.points[0].on_boundary);
}

TEST(CriticalPoints, MinimaAgreeWithTheGradient) {
  for (const Fixture& f : Fixtures()) {
    auto s = *ExplicitStructure::Build(f.topo, {});
    const auto points = *RunCriticalPoints(*s, f.order, {.boundary_rule = BoundaryRule::kNone}, {});
    const auto gradient = *RunDiscreteGradient(*s, f.order, {});
    EXPECT_EQ(points.counts[int(CriticalType::kMinimum)], gradient.critical_cells[0]);
  }
}

TEST(DiscreteGradient, ValidAndIdenticalOnEveryStructureAndMode) {
  for (const Fixture& f : Fixtures()) {
    auto explicit_structure = *ExplicitStructure::Build(f.topo, {});
    const DiscreteGradientResult reference = *RunDiscreteGradient(*explicit_structure, f.order, {});
    testing::ExpectValidGradient(reference, *explicit_structure);
    const std::string pairs = reference.PairsDigest(*f.topo);
    const std::string critical = reference.CriticalCellsDigest(*f.topo);
    auto check = [&](const DiscreteGradientResult& r, const std::string& label) {
      EXPECT_EQ(r.critical_cells, reference.critical_cells) << label;
      EXPECT_EQ(r.PairsDigest(*f.topo), pairs) << label;
      EXPECT_EQ(r.CriticalCellsDigest(*f.topo), critical) << label;
    };
    // The persistence arrays only: the same pairs, read from down[3] for d = 2.
    const auto kept =
        *RunDiscreteGradient(*explicit_structure, f.order, {}, GradientArrays::kPersistence);
    EXPECT_TRUE(kept.gradient.up[2].empty());
    check(kept, "explicit, persistence arrays");
    for (int consumers : {1, 2}) {
      CompactStructure compact(f.topo, {.cache_ratio = 0.1, .consumers = consumers});
      check(*RunDiscreteGradient(compact, f.order, {.consumers = consumers}), "compact");
      for (Prefetch p : {Prefetch::kLinear, Prefetch::kSpatial, Prefetch::kAdaptive}) {
        auto actopo = *ActopoStructure::Create(f.topo, {.consumers = consumers,
                                                        .producers = 3,
                                                        .buffer_ratio = 0.05,
                                                        .prefetch = p,
                                                        .precompute = Precompute::kDeclared,
                                                        .declared = DiscreteGradientDeclared()});
        check(*RunDiscreteGradient(*actopo, f.order, {.consumers = consumers}),
              std::string(PrefetchName(p)));
      }
    }
  }
}

}  // namespace
}  // namespace actopo
