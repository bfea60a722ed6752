#include "server/results/result_files.h"

#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <numeric>
#include <string>

#include "gmock/gmock.h"
#include "gtest/gtest.h"
#include "server/algorithms/morse_smale.h"
#include "server/algorithms/vertex_order.h"
#include "server/core/explicit_structure.h"
#include "server/core/partition.h"
#include "server/core/testing/oracle.h"
#include "server/core/testing/status.h"
#include "server/core/testing/test_meshes.h"

namespace actopo {
namespace {

using ::testing::ElementsAre;

template <class T>
const std::vector<T>& Get(const std::vector<io::NamedArray>& arrays, const std::string& name) {
  for (const io::NamedArray& a : arrays) {
    if (a.name == name) return std::get<std::vector<T>>(a.values);
  }
  ADD_FAILURE() << "no array " << name;
  static const std::vector<T> kEmpty;
  return kEmpty;
}

struct Diagram {
  Mesh mesh;
  std::shared_ptr<const Topology> topology;
  PersistenceDiagramResult result;
};

Diagram MakeDiagram() {
  Diagram d{testing::Lattice(6, 5, 4, 9)};
  d.topology =
      OkValue(Topology::Build(d.mesh, OctreeBlocks(d.mesh.points, {.bucket_capacity = 20})));
  auto structure = OkValue(ExplicitStructure::Build(d.topology, {}));
  const std::vector<double>& scalars = d.mesh.point_fields[0].values;
  d.result =
      OkValue(RunPersistenceDiagram(*structure, VertexOrder(*d.topology, scalars), scalars, {}));
  return d;
}

// The boundary flags results report are the oracle's, asked in any order, and a block is
// computed only when one of its vertices is asked about, once.
TEST(VertexBoundary, EqualsTheOracleBlockByBlockOnDemand) {
  const Mesh mesh = testing::Lattice(7, 6, 5, 3);
  const auto topology =
      OkValue(Topology::Build(mesh, OctreeBlocks(mesh.points, {.bucket_capacity = 20})));
  ASSERT_GT(topology->num_blocks(), 4);
  const testing::RelationOracle oracle(*topology);
  const VertexBoundary boundary(*topology);
  EXPECT_EQ(boundary.blocks_computed(), 0);
  const int32_t b = topology->num_blocks() / 2;
  for (SimplexId v = topology->block_vertex_begin(b); v < topology->block_vertex_begin(b + 1);
       ++v) {
    EXPECT_EQ(boundary(v), oracle.rows(Relation::kVB)[v][0] == 1) << v;
  }
  EXPECT_EQ(boundary.blocks_computed(), 1);
  int boundary_vertices = 0;
  const SimplexId n = topology->num_vertices();
  for (SimplexId i = 0; i < n; ++i) {
    const SimplexId v = SimplexId((int64_t(i) * 7919) % n);  // 7919 is prime, n is not a multiple
    boundary_vertices += boundary(v);
    EXPECT_EQ(boundary(v), oracle.rows(Relation::kVB)[v][0] == 1) << v;
  }
  EXPECT_EQ(boundary.blocks_computed(), topology->num_blocks());
  EXPECT_GT(boundary_vertices, 0);
  EXPECT_LT(boundary_vertices, n);
}

TEST(VertexBoundary, PrepareComputesTheBlocksOfTheVerticesGivenOnSeveralThreads) {
  const Mesh mesh = testing::Lattice(7, 6, 5, 3);
  const auto topology =
      OkValue(Topology::Build(mesh, OctreeBlocks(mesh.points, {.bucket_capacity = 20})));
  ASSERT_GT(topology->num_blocks(), 4);
  const testing::RelationOracle oracle(*topology);
  const VertexBoundary boundary(*topology);
  // Two vertices of the first block, one of the last: two blocks.
  const int32_t last = topology->num_blocks() - 1;
  const std::vector<SimplexId> some = {topology->block_vertex_begin(0),
                                       topology->block_vertex_begin(1) - 1,
                                       topology->block_vertex_begin(last)};
  boundary.Prepare(some, 3);
  EXPECT_EQ(boundary.blocks_computed(), 2);
  boundary.Prepare(some, 3);  // nothing left to compute
  EXPECT_EQ(boundary.blocks_computed(), 2);
  std::vector<SimplexId> every(size_t(topology->num_vertices()));
  std::iota(every.begin(), every.end(), 0);
  boundary.Prepare(every, 3);
  EXPECT_EQ(boundary.blocks_computed(), topology->num_blocks());
  for (SimplexId v = 0; v < topology->num_vertices(); ++v) {
    EXPECT_EQ(boundary(v), oracle.rows(Relation::kVB)[v][0] == 1) << v;
  }
  EXPECT_EQ(boundary.blocks_computed(), topology->num_blocks());  // the calls only read
}

TEST(PersistenceDiagramOutputs, TtkDiagramGridWithItsDiagonal) {
  Diagram d = MakeDiagram();
  const ResultContext context{d.mesh, *d.topology, "height", d.mesh.point_fields[0].values,
                              std::make_shared<VertexBoundary>(*d.topology)};
  const ResultOutputs out = BuildOutputs(context, d.result);
  ASSERT_EQ(out.poly_data.size(), 1u);
  EXPECT_EQ(out.poly_data[0].first, "diagram");
  const io::PolyData& grid = out.poly_data[0].second;
  const size_t n = d.result.pairs.size();
  ASSERT_GT(n, 2u);
  ASSERT_EQ(grid.points.size(), 3 * 2 * n);
  ASSERT_EQ(grid.line_offsets.size(), n + 2);  // a line per pair and the diagonal
  const auto& ids = Get<int32_t>(grid.cell_arrays, "PairIdentifier");
  const auto& types = Get<int32_t>(grid.cell_arrays, "PairType");
  const auto& persistence = Get<double>(grid.cell_arrays, "Persistence");
  const auto& finite = Get<int8_t>(grid.cell_arrays, "IsFinite");
  const auto& vertex = Get<int32_t>(grid.point_arrays, "ttkVertexScalarField");
  const auto& critical = Get<int32_t>(grid.point_arrays, "CriticalType");
  for (size_t i = 0; i < n; ++i) {
    const PersistencePair& p = d.result.pairs[i];
    EXPECT_EQ(ids[i], int32_t(i));
    EXPECT_EQ(types[i], p.type);
    EXPECT_EQ(persistence[i], p.Persistence());
    EXPECT_EQ(finite[i], p.finite());
    EXPECT_EQ(vertex[2 * i], p.birth);
    EXPECT_EQ(vertex[2 * i + 1], p.death);
    EXPECT_EQ(critical[2 * i], p.type);
    // Points at (birth, birth) and (birth, death).
    EXPECT_EQ(grid.points[6 * i + 0], p.birth_value);
    EXPECT_EQ(grid.points[6 * i + 1], p.birth_value);
    EXPECT_EQ(grid.points[6 * i + 4], p.death_value);
  }
  // The infinite pair of the global minimum dies at the global maximum, a "maximum".
  EXPECT_EQ(critical[1], 3);
  EXPECT_EQ(finite[0], 0);
  // The diagonal: first point to the last pair's birth point, PairIdentifier -1.
  EXPECT_EQ(ids[n], -1);
  EXPECT_EQ(types[n], -1);
  EXPECT_EQ(persistence[n], 2 * persistence[0]);
  EXPECT_THAT(std::vector<int32_t>(grid.line_connectivity.end() - 2, grid.line_connectivity.end()),
              ElementsAre(0, int32_t(2 * (n - 1))));
  // Coordinates: the vertices' positions, three floats per point.
  const auto& coordinates = Get<float>(grid.point_arrays, "Coordinates");
  ASSERT_EQ(coordinates.size(), 3 * 2 * n);
  EXPECT_EQ(coordinates[3], float(d.mesh.points[3 * size_t(d.result.pairs[0].death)]));

  ASSERT_EQ(out.tables.size(), 1u);
  const auto& curve = out.tables[0].second;
  const auto& curve_type = Get<int8_t>(curve, "PairType");
  const auto& alive = Get<int32_t>(curve, "NumberOfPairs");
  // The curve of all pairs comes last and starts with every pair.
  const size_t all = std::find(curve_type.begin(), curve_type.end(), -1) - curve_type.begin();
  ASSERT_LT(all, alive.size());
  EXPECT_EQ(alive[all], int32_t(n));
}

TEST(PersistenceDiagramOutputs, EmbeddedInTheDomainAndWritten) {
  Diagram d = MakeDiagram();
  d.result.embed_in_domain = true;
  const ResultContext context{d.mesh, *d.topology, "height", d.mesh.point_fields[0].values,
                              std::make_shared<VertexBoundary>(*d.topology)};
  const ResultOutputs out = BuildOutputs(context, d.result);
  const io::PolyData& grid = out.poly_data[0].second;
  const size_t n = d.result.pairs.size();
  EXPECT_EQ(grid.line_offsets.size(), n + 1);  // no diagonal
  const PersistencePair& p = d.result.pairs[1];
  for (int k = 0; k < 3; ++k) {
    EXPECT_EQ(grid.points[6 + k], d.mesh.points[3 * size_t(p.birth) + k]);
    EXPECT_EQ(grid.points[9 + k], d.mesh.points[3 * size_t(p.death) + k]);
  }
  const std::filesystem::path dir =
      std::filesystem::path(::testing::TempDir()) / ("actopo_results_" + std::to_string(getpid()));
  std::filesystem::create_directories(dir);
  const std::string prefix = (dir / "run").string();
  const auto written = WriteResultFiles(prefix, context, d.result);
  ASSERT_TRUE(written.ok()) << written.status();
  EXPECT_THAT(*written, ElementsAre(prefix + "_diagram.vtu", prefix + "_persistence_curve.csv"));
  std::ifstream csv(prefix + "_persistence_curve.csv");
  std::string header;
  std::getline(csv, header);
  EXPECT_EQ(header, "PairType,Persistence,NumberOfPairs");
  csv.close();
  std::filesystem::remove_all(dir);
}

TEST(SimplificationOutputs, FieldAndOrderStreamedAndWritten) {
  Mesh mesh = testing::Lattice(6, 5, 4, 9);
  auto topology =
      OkValue(Topology::Build(mesh, OctreeBlocks(mesh.points, {.bucket_capacity = 20})));
  auto structure = OkValue(ExplicitStructure::Build(topology, {}));
  const std::vector<double>& scalars = mesh.point_fields[0].values;
  const SimplificationResult r =
      OkValue(RunTopologicalSimplification(*structure, VertexOrder(*topology, scalars), scalars,
                                           {.threshold = 0.2, .relative = true}, {}));
  ASSERT_GT(r.stats.changed_values, 0);
  const ResultContext context{mesh, *topology, "height", scalars,
                              std::make_shared<VertexBoundary>(*topology)};
  const ResultOutputs out = BuildOutputs(context, r);
  ASSERT_EQ(out.simplified.size(), 2u);
  EXPECT_EQ(out.simplified[0].name, "height");
  EXPECT_EQ(std::get<std::vector<double>>(out.simplified[0].values), r.scalars);
  EXPECT_EQ(out.simplified[1].name, "height_Order");
  const std::filesystem::path dir = std::filesystem::path(::testing::TempDir()) /
                                    ("actopo_simplified_" + std::to_string(getpid()));
  std::filesystem::create_directories(dir);
  const auto written = WriteResultFiles((dir / "run").string(), context, r);
  ASSERT_TRUE(written.ok()) << written.status();
  EXPECT_THAT(*written, ElementsAre((dir / "run_simplified.vtu").string()));
  EXPECT_GT(std::filesystem::file_size(dir / "run_simplified.vtu"), 0u);
  std::filesystem::remove_all(dir);
}

// Separatrices: one polyline per separatrix through its cells' barycentres in order (points
// placed on several threads), and the critical points' IsOnBoundary as the oracle's VB.
TEST(MorseSmaleOutputs, SeparatrixPointsAreTheirCellsBarycentres) {
  Mesh mesh = testing::Lattice(9, 8, 7, 9);
  auto topology =
      OkValue(Topology::Build(mesh, OctreeBlocks(mesh.points, {.bucket_capacity = 30})));
  auto structure = OkValue(ExplicitStructure::Build(topology, {}));
  const std::vector<double>& scalars = mesh.point_fields[0].values;
  const MorseSmaleResult r = OkValue(RunMorseSmale(*structure, VertexOrder(*topology, scalars),
                                                   *InputCorners(*topology, mesh.tetrahedra), {}));
  ASSERT_GT(r.separatrices.size(), 10u);
  const ResultContext context{mesh, *topology, "height", scalars,
                              std::make_shared<VertexBoundary>(*topology)};
  const ResultOutputs out = BuildOutputs(context, r);
  ASSERT_EQ(out.poly_data.size(), 2u);
  ASSERT_EQ(out.poly_data[1].first, "separatrices");
  const io::PolyData& seps = out.poly_data[1].second;
  ASSERT_EQ(seps.line_offsets.size(), r.separatrices.size() + 1);
  size_t point = 0;
  for (size_t i = 0; i < r.separatrices.size(); ++i) {
    ASSERT_EQ(seps.line_offsets[i], int32_t(point)) << "separatrix " << i;
    const Separatrix& s = r.separatrices[i];
    for (size_t j = 0; j < s.path.size(); ++j) {
      const Cell cell = s.cell(j);
      const std::vector<SimplexId> vertices = CellInputVertices(*topology, cell.dim, cell.id);
      for (int k = 0; k < 3; ++k) {
        double sum = 0;
        for (SimplexId v : vertices) sum += mesh.points[3 * size_t(v) + k];
        EXPECT_EQ(seps.points[3 * point + k], sum / double(vertices.size()))
            << "separatrix " << i << ", point " << point;
      }
      EXPECT_EQ(seps.line_connectivity[point], int32_t(point));
      ++point;
    }
  }
  EXPECT_EQ(seps.points.size(), 3 * point);
  EXPECT_EQ(seps.line_connectivity.size(), point);

  const testing::RelationOracle oracle(*topology);
  const io::PolyData& critical = out.poly_data[0].second;
  const auto& highest = Get<int32_t>(critical.point_arrays, "ttkVertexScalarField");
  const auto& on_boundary = Get<int8_t>(critical.point_arrays, "IsOnBoundary");
  ASSERT_EQ(highest.size(), on_boundary.size());
  int boundary_cells = 0;
  for (size_t i = 0; i < highest.size(); ++i) {
    const SimplexId v = topology->vertex_internal_id(highest[i]);
    EXPECT_EQ(on_boundary[i], oracle.rows(Relation::kVB)[v][0]) << "vertex " << highest[i];
    boundary_cells += on_boundary[i];
  }
  EXPECT_GT(boundary_cells, 0);  // else the flags would not be seen set
}

// The complex after a simplification reports the simplified field: its values at the critical
// cells' highest vertices, ranked by the simplified order.
TEST(SimplificationOutputs, SimplifiedMorseSmaleReportsTheSimplifiedField) {
  Mesh mesh = testing::Lattice(7, 6, 5, 9);
  auto topology =
      OkValue(Topology::Build(mesh, OctreeBlocks(mesh.points, {.bucket_capacity = 20})));
  auto structure = OkValue(ExplicitStructure::Build(topology, {}));
  const std::vector<double>& scalars = mesh.point_fields[0].values;
  SimplifiedMorseSmaleResult r;
  r.simplification =
      OkValue(RunTopologicalSimplification(*structure, VertexOrder(*topology, scalars), scalars,
                                           {.threshold = 0.2, .relative = true}, {}));
  r.morse_smale = OkValue(RunMorseSmale(*structure, r.simplification.internal_order,
                                        *InputCorners(*topology, mesh.tetrahedra), {}));
  const ResultContext context{mesh, *topology, "height", scalars,
                              std::make_shared<VertexBoundary>(*topology)};
  const ResultOutputs out = BuildOutputs(context, r);
  const io::PolyData& points = out.poly_data[0].second;
  ASSERT_EQ(out.poly_data[0].first, "critical_points");
  const auto& vertex = Get<int32_t>(points.point_arrays, "ttkVertexScalarField");
  const auto& value = Get<double>(points.point_arrays, "height");
  ASSERT_FALSE(vertex.empty());
  int64_t flattened = 0;  // critical cells whose highest vertex the simplification moved
  for (size_t i = 0; i < vertex.size(); ++i) {
    EXPECT_EQ(value[i], r.simplification.scalars[vertex[i]]) << "vertex " << vertex[i];
    flattened += value[i] != scalars[vertex[i]];
  }
  EXPECT_GT(flattened, 0);  // else this test would not see the input field reported
  EXPECT_EQ(out.simplified.size(), 2u);
}

}  // namespace
}  // namespace actopo
