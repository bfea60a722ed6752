// critical-points and discrete-gradient against upstream TTK's results on the same files
// (../shared/data/expected-ttk.json): counts and SHA-256 digests, on every structure.
#include <fstream>

#include "gtest/gtest.h"
#include "nlohmann/json.hpp"
#include "server/algorithms/critical_points.h"
#include "server/algorithms/discrete_gradient.h"
#include "server/algorithms/morse_smale.h"
#include "server/algorithms/testing/gradient_checks.h"
#include "server/algorithms/vertex_order.h"
#include "server/core/actopo_structure.h"
#include "server/core/compact_structure.h"
#include "server/core/explicit_structure.h"
#include "server/core/partition.h"
#include "server/io/test_data.h"
#include "server/io/vtk_reader.h"

namespace actopo {
namespace {

using Json = nlohmann::json;

struct Case {
  std::string file, field;
  Json expected;  // the "upstream" entry
};

std::vector<Case> Cases() {
  std::vector<Case> out;
  std::ifstream in(io::testing::DataDir() + "/expected-ttk.json");
  if (!in) return out;
  const Json all = Json::parse(in);
  for (const auto& [file, fields] : all.items()) {
    for (const auto& [field, entry] : fields.items()) out.push_back({file, field, entry["upstream"]});
  }
  return out;
}

struct Loaded {
  std::shared_ptr<const Topology> topology;
  std::vector<SimplexId> order;
  std::vector<SimplexId> tetrahedra;  // as in the file
};

Loaded Load(const std::string& file, const std::string& field) {
  auto mesh = io::ReadMesh(io::testing::DataDir() + "/" + file);
  EXPECT_TRUE(mesh.ok()) << mesh.status();
  const int f = *SelectScalarField(*mesh, field);
  auto topo = *Topology::Build(*mesh, OctreeBlocks(mesh->points, {.bucket_capacity = 1000}));
  return {topo, VertexOrder(*topo, mesh->point_fields[f].values), mesh->tetrahedra};
}

class MatchesTtk : public io::testing::DataTest {};

TEST_F(MatchesTtk, CriticalPointsAndDiscreteGradient) {
  const std::vector<Case> cases = Cases();
  ASSERT_FALSE(cases.empty()) << "expected-ttk.json not found in " << io::testing::DataDir();
  for (const Case& c : cases) {
    SCOPED_TRACE(c.file + " / " + c.field);
    const Loaded in = Load(c.file, c.field);
    auto explicit_structure = *ExplicitStructure::Build(in.topology, {});
    CompactStructure compact(in.topology, {.cache_ratio = 0.2, .consumers = 2});
    auto actopo = *ActopoStructure::Create(in.topology, {.consumers = 2, .producers = 2});

    const Json& cp = c.expected["critical_points"];
    for (const CriticalPointsResult& r :
         {*RunCriticalPoints(*explicit_structure, in.order, {}, {}),
          *RunCriticalPoints(compact, in.order, {}, {.consumers = 2}),
          *RunCriticalPoints(*actopo, in.order, {}, {.consumers = 2})}) {
      EXPECT_EQ(r.counts[int(CriticalType::kMinimum)], cp["counts"]["minimum"].get<int64_t>());
      EXPECT_EQ(r.counts[int(CriticalType::kSaddle1)], cp["counts"]["saddle1"].get<int64_t>());
      EXPECT_EQ(r.counts[int(CriticalType::kSaddle2)], cp["counts"]["saddle2"].get<int64_t>());
      EXPECT_EQ(r.counts[int(CriticalType::kMaximum)], cp["counts"]["maximum"].get<int64_t>());
      EXPECT_EQ(r.counts[int(CriticalType::kDegenerate)],
                cp["counts"]["degenerate"].get<int64_t>());
      EXPECT_EQ(r.VerticesDigest(), cp["vertices_sha256"].get<std::string>());
    }

    const Json& dg = c.expected["discrete_gradient"];
    const DiscreteGradientResult reference = *RunDiscreteGradient(*explicit_structure, in.order, {});
    testing::ExpectValidGradient(reference, *explicit_structure);
    for (const DiscreteGradientResult& r :
         {reference, *RunDiscreteGradient(compact, in.order, {.consumers = 2}),
          *RunDiscreteGradient(*actopo, in.order, {.consumers = 2})}) {
      EXPECT_EQ(Json(r.critical_cells), dg["critical_cells"]);
      EXPECT_EQ(Json(r.pairs), dg["pairs_count"]);
      EXPECT_EQ(r.CriticalCellsDigest(*in.topology), dg["critical_cells_sha256"].get<std::string>());
      EXPECT_EQ(r.PairsDigest(*in.topology), dg["pairs_sha256"].get<std::string>());
    }
  }
}

TEST_F(MatchesTtk, MorseSmale) {
  const std::vector<Case> cases = Cases();
  ASSERT_FALSE(cases.empty());
  for (const Case& c : cases) {
    SCOPED_TRACE(c.file + " / " + c.field);
    const Loaded in = Load(c.file, c.field);
    const Json& ms = c.expected["morse_smale"];
    auto explicit_structure = *ExplicitStructure::Build(in.topology, {});
    auto actopo = *ActopoStructure::Create(
        in.topology, {.consumers = 2, .producers = 2, .prefetch = Prefetch::kSpatial});
    CompactStructure compact(in.topology, {.cache_ratio = 0.1});
    for (const MorseSmaleResult& r :
         {*RunMorseSmale(*explicit_structure, in.order, in.tetrahedra, {}),
          *RunMorseSmale(*actopo, in.order, in.tetrahedra, {.consumers = 2}),
          *RunMorseSmale(compact, in.order, in.tetrahedra, {})}) {
      EXPECT_EQ(Json(r.gradient.critical_cells), ms["critical_cells"]);
      EXPECT_EQ(r.CountSeparatrices(SeparatrixType::kDescending),
                ms["separatrices"]["descending"].get<int64_t>());
      EXPECT_EQ(r.CountSeparatrices(SeparatrixType::kAscending),
                ms["separatrices"]["ascending"].get<int64_t>());
      EXPECT_EQ(r.CountSeparatrices(SeparatrixType::kSaddleConnector),
                ms["separatrices"]["saddle_connectors"].get<int64_t>());
      EXPECT_EQ(r.Segments(), ms["separatrices"]["segments"].get<int64_t>());
      EXPECT_EQ(MorseSmaleResult::Regions(r.descending), ms["regions"]["descending"].get<int64_t>());
      EXPECT_EQ(MorseSmaleResult::Regions(r.ascending), ms["regions"]["ascending"].get<int64_t>());
      EXPECT_EQ(MorseSmaleResult::Regions(r.morse_smale),
                ms["regions"]["morse_smale"].get<int64_t>());
      EXPECT_EQ(MorseSmaleResult::SegmentationDigest(r.descending),
                ms["segmentation_sha256"]["descending"].get<std::string>());
      EXPECT_EQ(MorseSmaleResult::SegmentationDigest(r.ascending),
                ms["segmentation_sha256"]["ascending"].get<std::string>());
      EXPECT_EQ(MorseSmaleResult::SegmentationDigest(r.morse_smale),
                ms["segmentation_sha256"]["morse_smale"].get<std::string>());
    }
  }
}

// Meshes TTK's reference does not cover: the gradient is still valid and structure-independent.
TEST_F(MatchesTtk, GradientInvariantsOnOtherMeshes) {
  for (const auto& [file, field] : {std::pair{"casting_tet.vtu", "eigenfunction4"},
                                    std::pair{"isabel02_s2_tet.vtu", "velocityMag"}}) {
    SCOPED_TRACE(file);
    const Loaded in = Load(file, field);
    auto explicit_structure = *ExplicitStructure::Build(in.topology, {});
    const DiscreteGradientResult reference = *RunDiscreteGradient(*explicit_structure, in.order, {});
    testing::ExpectValidGradient(reference, *explicit_structure);
    auto actopo = *ActopoStructure::Create(in.topology, {.producers = 2,
                                                         .prefetch = Prefetch::kAdaptive});
    const DiscreteGradientResult r = *RunDiscreteGradient(*actopo, in.order, {});
    EXPECT_EQ(r.PairsDigest(*in.topology), reference.PairsDigest(*in.topology));
  }
}

}  // namespace
}  // namespace actopo
