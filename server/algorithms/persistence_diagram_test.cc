#include "server/algorithms/persistence_diagram.h"

#include <algorithm>
#include <map>
#include <random>
#include <set>

#include "gtest/gtest.h"
#include "server/algorithms/vertex_order.h"
#include "server/core/actopo_structure.h"
#include "server/core/compact_structure.h"
#include "server/core/explicit_structure.h"
#include "server/core/partition.h"
#include "server/core/testing/status.h"
#include "server/core/testing/test_meshes.h"

namespace actopo {
namespace {

// (type, birth vertex, death vertex, finite), input ids.
using PairTuple = std::array<int64_t, 4>;

struct Input {
  Mesh mesh;
  std::shared_ptr<const Topology> topo;
  std::vector<SimplexId> order;
  std::vector<double> scalars;
};

Input Make(Mesh mesh, int block_size, int field = 0) {
  auto topo =
      OkValue(Topology::Build(mesh, OctreeBlocks(mesh.points, {.bucket_capacity = block_size})));
  std::vector<double> scalars = mesh.point_fields[field].values;
  auto order = VertexOrder(*topo, scalars);
  return {std::move(mesh), topo, std::move(order), std::move(scalars)};
}

// A lattice without the cubes `drop` says to remove (cube corner i, j, k), its field replaced by
// noise when `seed` is not 0: many critical cells of every index.
Mesh Carved(int n, uint64_t seed, const std::function<bool(int, int, int)>& drop) {
  Mesh lattice = testing::Lattice(n, n, n);
  Mesh m;
  m.points = lattice.points;
  m.point_fields = lattice.point_fields;
  for (SimplexId t = 0; t < lattice.num_tetrahedra(); ++t) {
    double c[3] = {0, 0, 0};
    for (int k = 0; k < 4; ++k) {
      for (int a = 0; a < 3; ++a)
        c[a] += lattice.points[3 * size_t(lattice.tetrahedra[4 * t + k]) + a];
    }
    if (drop(int(c[0] / 4), int(c[1] / 4), int(c[2] / 4))) continue;
    m.tetrahedra.insert(m.tetrahedra.end(), &lattice.tetrahedra[4 * t],
                        &lattice.tetrahedra[4 * t + 4]);
  }
  if (seed != 0) {
    std::mt19937_64 rng(seed);
    std::uniform_real_distribution<double> noise(0, 1);
    for (double& v : m.point_fields[0].values) v = noise(rng);
  }
  return m;
}

// Persistence pairs of the lower-star filtration, simplices ordered by their vertices' orders
// (highest first, lexicographically), by the textbook reduction of the full boundary matrix:
// slow and obviously right. Pairs whose birth and death share their highest vertex (persistence
// zero in the vertex order) are left out, as every gradient pair is one.
std::set<PairTuple> OraclePairs(const Input& in) {
  const Topology& topo = *in.topo;
  std::map<std::vector<SimplexId>, int> index;  // sorted internal vertex tuple -> simplex
  std::vector<std::vector<SimplexId>> simplices;
  for (SimplexId t = 0; t < topo.num_tetrahedra(); ++t) {
    const auto tv = topo.tetrahedron(t);
    for (int mask = 1; mask < 16; ++mask) {
      std::vector<SimplexId> s;
      for (int k = 0; k < 4; ++k) {
        if (mask >> k & 1) s.push_back(tv[k]);
      }
      if (index.emplace(s, int(simplices.size())).second) simplices.push_back(s);
    }
  }
  const auto key = [&](const std::vector<SimplexId>& s) {
    std::vector<SimplexId> k;
    for (SimplexId v : s) k.push_back(in.order[v]);
    std::sort(k.rbegin(), k.rend());
    return k;
  };
  std::vector<int> filtration(simplices.size());
  std::iota(filtration.begin(), filtration.end(), 0);
  std::sort(filtration.begin(), filtration.end(),
            [&](int a, int b) { return key(simplices[a]) < key(simplices[b]); });
  std::vector<int> position(simplices.size());
  for (size_t i = 0; i < filtration.size(); ++i) position[filtration[i]] = int(i);
  const auto top = [&](int s) {  // the highest vertex, input id
    SimplexId best = simplices[s][0];
    for (SimplexId v : simplices[s]) {
      if (in.order[v] > in.order[best]) best = v;
    }
    return topo.vertex_input_id(best);
  };
  // Columns by filtration position: sorted positions of the faces.
  std::vector<std::vector<int>> columns(filtration.size());
  std::map<int, int> low_owner;  // pivot -> column
  std::vector<bool> paired(filtration.size(), false);
  std::set<PairTuple> out;
  for (size_t j = 0; j < filtration.size(); ++j) {
    const auto& s = simplices[filtration[j]];
    if (s.size() > 1) {
      for (size_t skip = 0; skip < s.size(); ++skip) {
        std::vector<SimplexId> face;
        for (size_t k = 0; k < s.size(); ++k) {
          if (k != skip) face.push_back(s[k]);
        }
        columns[j].push_back(position[index.at(face)]);
      }
      std::sort(columns[j].begin(), columns[j].end());
    }
    std::vector<int>& col = columns[j];
    while (!col.empty() && low_owner.contains(col.back())) {
      const std::vector<int>& other = columns[low_owner[col.back()]];
      std::vector<int> sum;
      std::set_symmetric_difference(col.begin(), col.end(), other.begin(), other.end(),
                                    std::back_inserter(sum));
      col = std::move(sum);
    }
    if (col.empty()) continue;
    const int birth = col.back();
    low_owner[birth] = int(j);
    paired[birth] = paired[j] = true;
    const int b = filtration[birth], d = filtration[j];
    if (top(b) != top(d)) out.insert({int64_t(simplices[b].size()) - 1, top(b), top(d), 1});
  }
  SimplexId global_max = 0;
  for (SimplexId v = 0; v < topo.num_vertices(); ++v) {
    if (in.order[v] > in.order[global_max]) global_max = v;
  }
  for (size_t j = 0; j < filtration.size(); ++j) {
    if (paired[j]) continue;
    const int s = filtration[j];
    out.insert({int64_t(simplices[s].size()) - 1, top(s), topo.vertex_input_id(global_max), 0});
  }
  return out;
}

std::set<PairTuple> NonZeroPairs(const PersistenceDiagramResult& r) {
  std::set<PairTuple> out;
  for (const PersistencePair& p : r.pairs) {
    if (!p.finite() || p.birth != p.death) out.insert({p.type, p.birth, p.death, p.finite()});
  }
  return out;
}

void ExpectConsistent(const PersistenceDiagramResult& r, std::span<const double> scalars) {
  // Every critical cell in exactly one pair.
  const auto& c = r.gradient.critical_cells;
  EXPECT_EQ(c[0], r.finite[0] + r.infinite[0]);
  EXPECT_EQ(c[1], r.finite[0] + r.finite[1] + r.infinite[1]);
  EXPECT_EQ(c[2], r.finite[1] + r.finite[2] + r.infinite[2]);
  EXPECT_EQ(c[3], r.finite[2]);
  // The diagram keeps only the pairings it follows; `critical` lists every critical cell.
  const auto critical = [&](int d, SimplexId c) {
    return std::binary_search(r.gradient.critical[d].begin(), r.gradient.critical[d].end(), c);
  };
  EXPECT_TRUE(r.gradient.gradient.down[2].empty());
  std::set<std::pair<int, SimplexId>> cells;
  for (const PersistencePair& p : r.pairs) {
    EXPECT_TRUE(critical(p.type, p.birth_cell));
    EXPECT_TRUE(cells.insert({p.type, p.birth_cell}).second) << "birth cell paired twice";
    if (p.finite()) {
      EXPECT_TRUE(critical(p.type + 1, p.death_cell));
      EXPECT_TRUE(cells.insert({p.type + 1, p.death_cell}).second) << "death cell paired twice";
    }
    EXPECT_GE(p.Persistence(), 0);
    EXPECT_EQ(p.birth_value, scalars[p.birth]);
    EXPECT_EQ(p.death_value, scalars[p.death]);
  }
}

TEST(PersistenceDiagram, EqualsTheFullBoundaryMatrixReduction) {
  struct Named {
    const char* name;
    Mesh mesh;
    std::array<int64_t, 3> betti;
  };
  const auto none = [](int, int, int) { return false; };
  // A solid torus (a column of cubes removed) and a ball with a cavity (the centre cube removed).
  const auto tunnel = [](int i, int j, int) { return i == 2 && j == 2; };
  const auto cavity = [](int i, int j, int k) { return i == 2 && j == 2 && k == 2; };
  for (Named m : {Named{"smooth ball", testing::Lattice(7, 6, 5, 31), {1, 0, 0}},
                  Named{"noisy ball", Carved(6, 7, none), {1, 0, 0}},
                  Named{"noisy torus", Carved(6, 11, tunnel), {1, 1, 0}},
                  Named{"noisy cavity", Carved(6, 13, cavity), {1, 0, 1}},
                  Named{"two components", testing::TwoComponents(), {2, 0, 0}}}) {
    SCOPED_TRACE(m.name);
    const Input in = Make(std::move(m.mesh), 17);
    auto structure = OkValue(ExplicitStructure::Build(in.topo, {}));
    const auto r = RunPersistenceDiagram(*structure, in.order, in.scalars, {});
    ASSERT_TRUE(r.ok()) << r.status();
    ExpectConsistent(*r, in.scalars);
    EXPECT_EQ(r->infinite, m.betti);
    EXPECT_GT(r->pairs.size(), 1u);
    EXPECT_EQ(NonZeroPairs(*r), OraclePairs(in));
    EXPECT_GT(r->finite[1], 0);  // saddle-saddle pairs were reduced
  }
}

// A triangle with three tetrahedra: the gradient's sweep records no links there, and the
// ascending paths read vertex stars instead, to the boundary matrix's pairs all the same.
TEST(PersistenceDiagram, CrowdedTrianglesReadVertexStars) {
  const Input in = Make(testing::NonManifold(), 4);
  ASSERT_TRUE(in.topo->has_crowded_triangles());
  auto structure = OkValue(ExplicitStructure::Build(in.topo, {}));
  const auto r = RunPersistenceDiagram(*structure, in.order, in.scalars, {});
  ASSERT_TRUE(r.ok()) << r.status();
  ExpectConsistent(*r, in.scalars);
  EXPECT_EQ(NonZeroPairs(*r), OraclePairs(in));
  CompactStructure compact(in.topo, {.cache_ratio = 0.05, .consumers = 2});
  EXPECT_EQ(RunPersistenceDiagram(compact, in.order, in.scalars, {.consumers = 2})->PairsDigest(),
            r->PairsDigest());
}

TEST(PersistenceDiagram, DoesNotDependOnTheStructureOrThreads) {
  const Input in = Make(Carved(7, 5, [](int i, int j, int) { return i == 3 && j == 2; }), 23);
  auto explicit_structure = OkValue(ExplicitStructure::Build(in.topo, {}));
  const auto reference =
      OkValue(RunPersistenceDiagram(*explicit_structure, in.order, in.scalars, {}));
  ASSERT_GT(reference.finite[1], 0);  // saddle-saddle pairs to reduce
  const auto pairs = [](const PersistenceDiagramResult& r) {
    std::vector<PairTuple> out;  // in the result's order, which is part of the contract
    for (const PersistencePair& p : r.pairs) out.push_back({p.type, p.birth, p.death, p.finite()});
    return out;
  };
  const auto expected = pairs(reference);
  for (int consumers : {1, 2, 3}) {
    const RunContext context{.consumers = consumers};
    EXPECT_EQ(
        pairs(OkValue(RunPersistenceDiagram(*explicit_structure, in.order, in.scalars, context))),
        expected);
    CompactStructure compact(in.topo, {.cache_ratio = 0.05, .consumers = consumers});
    EXPECT_EQ(pairs(OkValue(RunPersistenceDiagram(compact, in.order, in.scalars, context))),
              expected);
    for (Prefetch p : {Prefetch::kLinear, Prefetch::kSpatial}) {
      auto actopo =
          OkValue(ActopoStructure::Create(in.topo, {.consumers = consumers,
                                                    .producers = 2,
                                                    .buffer_ratio = 0.05,
                                                    .prefetch = p,
                                                    .declared = PersistenceDiagramDeclared()}));
      EXPECT_EQ(pairs(OkValue(RunPersistenceDiagram(*actopo, in.order, in.scalars, context))),
                expected)
          << consumers << " consumers, " << PrefetchName(p);
    }
  }
  // The block size changes internal ids, not the diagram.
  const Input other = Make(Carved(7, 5, [](int i, int j, int) { return i == 3 && j == 2; }), 3);
  auto s = OkValue(ExplicitStructure::Build(other.topo, {}));
  EXPECT_EQ(RunPersistenceDiagram(*s, other.order, other.scalars, {})->PairsDigest(),
            reference.PairsDigest());
}

TEST(PersistenceDiagram, PairsAreSortedByBirthAndTheCurveCountsSurvivors) {
  const Input in = Make(Carved(6, 3, [](int, int, int) { return false; }), 50);
  auto structure = OkValue(ExplicitStructure::Build(in.topo, {}));
  const auto r = OkValue(RunPersistenceDiagram(*structure, in.order, in.scalars, {}));
  for (size_t i = 1; i < r.pairs.size(); ++i) {
    EXPECT_LE(in.scalars[r.pairs[i - 1].birth], in.scalars[r.pairs[i].birth]);
  }
  const PersistenceCurve all = ComputePersistenceCurve(r, -1);
  ASSERT_FALSE(all.pairs.empty());
  EXPECT_EQ(all.pairs.front(), int32_t(r.pairs.size()));
  EXPECT_DOUBLE_EQ(all.persistence.back(), r.MaxPersistence());
  for (size_t i = 0; i < all.persistence.size(); ++i) {
    const auto alive = std::count_if(r.pairs.begin(), r.pairs.end(), [&](const PersistencePair& p) {
      return p.Persistence() >= all.persistence[i];
    });
    EXPECT_EQ(all.pairs[i], alive);
  }
  const PersistenceCurve minima = ComputePersistenceCurve(r, 0);
  EXPECT_EQ(minima.pairs.front(), r.finite[0] + r.infinite[0]);
}

TEST(PersistenceDiagram, RejectsScalarsOfAnotherMesh) {
  const Input in = Make(testing::Lattice(4, 4, 4), 10);
  auto structure = OkValue(ExplicitStructure::Build(in.topo, {}));
  const std::vector<double> short_field(3, 0.0);
  const auto r = RunPersistenceDiagram(*structure, in.order, short_field, {});
  EXPECT_EQ(r.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_NE(r.status().message().find("3 scalars"), std::string::npos) << r.status();
}

}  // namespace
}  // namespace actopo
