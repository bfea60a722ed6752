// Relations on real meshes and built-in samples: exact against the brute-force oracle on the
// small ones (including the deliberately non-manifold manifoldCheck meshes), and the counts and
// identities of SEMANTICS.md / ../shared/data/README.md on the larger ones.
#include <set>

#include "gtest/gtest.h"
#include "server/algorithms/topo_relations.h"
#include "server/core/compact_structure.h"
#include "server/core/explicit_structure.h"
#include "server/core/partition.h"
#include "server/core/testing/oracle.h"
#include "server/core/testing/relation_checks.h"
#include "server/core/testing/status.h"
#include "server/io/samples.h"
#include "server/io/test_data.h"
#include "server/io/vtk_reader.h"

namespace actopo {
namespace {

using io::testing::DataTest;

std::shared_ptr<const Topology> Partitioned(const Mesh& mesh, int block_size) {
  auto topology = Topology::Build(mesh, OctreeBlocks(mesh.points, {.bucket_capacity = block_size}));
  EXPECT_TRUE(topology.ok()) << topology.status();
  return *topology;
}

void ExpectExactRelations(const Mesh& mesh, const std::string& name) {
  for (int block_size : {1, 7, 100, 1000}) {
    auto topo = Partitioned(mesh, block_size);
    testing::RelationOracle oracle(*topo);
    const std::string label = name + " block size " + std::to_string(block_size);
    auto explicit_structure = OkValue(ExplicitStructure::Build(topo, {}));
    auto explicit_reader = explicit_structure->NewReader();
    EXPECT_EQ(testing::CompareWithOracle(explicit_reader, oracle, label + " explicit"), 0);
    CompactStructure compact(topo, {.cache_ratio = 0.2});
    auto compact_reader = compact.NewReader();
    EXPECT_EQ(testing::CompareWithOracle(compact_reader, oracle, label + " compact"), 0);
    testing::CompareRandomAccess(compact_reader, oracle, 3, 200, label + " compact");
  }
}

class SmallMeshes : public DataTest, public ::testing::WithParamInterface<const char*> {};

TEST_P(SmallMeshes, EveryRelationMatchesOracle) {
  const auto mesh = io::ReadMesh(DataFile(GetParam()));
  ASSERT_TRUE(mesh.ok()) << mesh.status();
  ExpectExactRelations(*mesh, GetParam());
}

INSTANTIATE_TEST_SUITE_P(ManifoldCheck, SmallMeshes,
                         ::testing::Values("manifoldCheck0_tet.vtu", "manifoldCheck1_tet.vtu",
                                           "manifoldCheck2_tet.vtu"));

TEST(Samples, AnalyticAndIrregularMatchOracle) {
  ExpectExactRelations(OkValue(io::MakeSample("wavelet:7")), "wavelet:7");
  ExpectExactRelations(OkValue(io::MakeSample("jittered:7")), "jittered:7");
}

struct Expected {
  const char* file;
  SimplexId v, e, f, t, boundary;
  int euler;
};

class LargerMeshes : public DataTest, public ::testing::WithParamInterface<Expected> {};

// The pairs of SEMANTICS.md are mutually inverse, TT is symmetric, VV are VE's other endpoints.
template <class Reader>
void ExpectInverses(Reader& r) {
  const Topology& topo = r.topology();
  auto contains = [](std::span<const SimplexId> row, SimplexId x) {
    return std::find(row.begin(), row.end(), x) != row.end();
  };
  int bad = 0;
  for (SimplexId v = 0; v < topo.num_vertices(); ++v) {
    const auto ve = r.vertex_edges(v);
    const auto vv = r.vertex_neighbors(v);
    if (ve.size() != vv.size()) ++bad;
    for (size_t i = 0; i < ve.size() && i < vv.size(); ++i) {
      const auto ev = r.edge_vertices(ve[i]);
      if (!contains(ev, v) || (ev[0] == v ? ev[1] : ev[0]) != vv[i]) ++bad;
    }
    for (SimplexId f : r.vertex_triangles(v)) bad += !contains(r.triangle_vertices(f), v);
    for (SimplexId t : r.vertex_star(v)) bad += !contains(r.tetrahedron_vertices(t), v);
  }
  for (SimplexId e = 0; e < topo.num_edges(); ++e) {
    for (SimplexId f : r.edge_triangles(e)) bad += !contains(r.triangle_edges(f), e);
    for (SimplexId t : r.edge_star(e)) bad += !contains(r.tetrahedron_edges(t), e);
  }
  for (SimplexId f = 0; f < topo.num_triangles(); ++f) {
    for (SimplexId t : r.triangle_star(f)) bad += !contains(r.tetrahedron_triangles(t), f);
    bad += r.triangle_on_boundary(f) != (r.triangle_star(f).size() == 1);
  }
  for (SimplexId t = 0; t < topo.num_tetrahedra(); ++t) {
    for (SimplexId e : r.tetrahedron_edges(t)) bad += !contains(r.edge_star(e), t);
    for (SimplexId f : r.tetrahedron_triangles(t)) bad += !contains(r.triangle_star(f), t);
    const std::vector<SimplexId> neighbors(r.tetrahedron_neighbors(t).begin(),
                                           r.tetrahedron_neighbors(t).end());
    for (SimplexId n : neighbors) bad += !contains(r.tetrahedron_neighbors(n), t);
  }
  EXPECT_EQ(bad, 0);
}

TEST_P(LargerMeshes, CountsIdentitiesAndStructuresAgree) {
  const Expected& x = GetParam();
  const auto mesh = io::ReadMesh(DataFile(x.file));
  ASSERT_TRUE(mesh.ok()) << mesh.status();
  auto topo = Partitioned(*mesh, 1000);
  EXPECT_EQ(topo->num_vertices(), x.v);
  EXPECT_EQ(topo->num_edges(), x.e);
  EXPECT_EQ(topo->num_triangles(), x.f);
  EXPECT_EQ(topo->num_tetrahedra(), x.t);
  EXPECT_EQ(int64_t(x.v) - x.e + x.f - x.t, x.euler);

  auto explicit_structure = OkValue(ExplicitStructure::Build(topo, {}));
  const TopoRelationsResult e = OkValue(RunTopoRelations(*explicit_structure, {.consumers = 2}));
  auto total = [&](Relation r) { return e.totals[Index(r)]; };
  const int64_t E = x.e, F = x.f, T = x.t;
  EXPECT_EQ(total(Relation::kVT), 4 * T);
  EXPECT_EQ(total(Relation::kVE), 2 * E);
  EXPECT_EQ(total(Relation::kVV), 2 * E);
  EXPECT_EQ(total(Relation::kVF), 3 * F);
  EXPECT_EQ(total(Relation::kET), 6 * T);
  EXPECT_EQ(total(Relation::kEF), 3 * F);
  EXPECT_EQ(total(Relation::kFT), 4 * T);
  EXPECT_EQ(total(Relation::kTT), 2 * (F - x.boundary));
  EXPECT_EQ(x.boundary, 2 * F - 4 * T);
  int64_t boundary = 0;
  for (SimplexId f = 0; f < topo->num_triangles(); ++f) boundary += topo->triangle_on_boundary(f);
  EXPECT_EQ(boundary, x.boundary);

  CompactStructure compact(topo, {.cache_ratio = 0.2, .consumers = 2});
  const TopoRelationsResult c = OkValue(RunTopoRelations(compact, {.consumers = 2}));
  EXPECT_EQ(c.totals, e.totals);
  EXPECT_EQ(c.checksum, e.checksum);

  auto reader = explicit_structure->NewReader();
  ExpectInverses(reader);
}

INSTANTIATE_TEST_SUITE_P(
    Data, LargerMeshes,
    ::testing::Values(Expected{"casting_tet.vtu", 14756, 82645, 125144, 57263, 21236, -8},
                      Expected{"fertility_tet.vtu", 14570, 84608, 130983, 60948, 18174, -3},
                      Expected{"isabel02_s2_tet.vtu", 51597, 292900, 471944, 230640, 21328, 1},
                      Expected{"viscousFingers001_s2_tet.vtu", 32768, 187488, 303676, 148955, 11532,
                               1}),
    [](const ::testing::TestParamInfo<Expected>& info) {
      std::string name = info.param.file;
      return name.substr(0, name.find('_'));
    });

}  // namespace
}  // namespace actopo
