// critical-points, discrete-gradient, morse-smale, persistence-diagram and the merge trees against
// upstream TTK's results on the same files (../shared/data/expected-ttk.json): counts and SHA-256
// digests, on every structure.
#include <cctype>
#include <fstream>
#include <set>
#include <type_traits>

#include "gtest/gtest.h"
#include "nlohmann/json.hpp"
#include "server/algorithms/critical_points.h"
#include "server/algorithms/discrete_gradient.h"
#include "server/algorithms/merge_tree.h"
#include "server/algorithms/morse_smale.h"
#include "server/algorithms/persistence_diagram.h"
#include "server/algorithms/testing/gradient_checks.h"
#include "server/algorithms/vertex_order.h"
#include "server/core/actopo_structure.h"
#include "server/core/compact_structure.h"
#include "server/core/explicit_structure.h"
#include "server/core/partition.h"
#include "server/core/testing/status.h"
#include "server/io/test_data.h"
#include "server/io/vtk_reader.h"
#include "tests/morse_smale_checks.h"

namespace actopo {
namespace {

using Json = nlohmann::json;

// The (file, field) pairs of expected-ttk.json, one test each. Listed here, not read from the
// file, so the tests exist whatever folder the test binary was listed with (ctest lists them at
// build time); EveryExpectedDatasetIsTested keeps the list equal to the file.
struct Case {
  std::string file, field;
};
const Case kCases[] = {
    {"manifoldCheck0_tet.vtu", "height"}, {"manifoldCheck1_tet.vtu", "height"},
    {"manifoldCheck2_tet.vtu", "height"}, {"fertility_tet.vtu", "eigenfunction4"},
    {"fertility_tet.vtu", "height"},      {"viscousFingers001_s2_tet.vtu", "density"},
};

Json ExpectedTtk() {
  std::ifstream in(io::testing::DataDir() + "/expected-ttk.json");
  return in ? Json::parse(in) : Json();
}

// The "upstream" entry of expected-ttk.json for `c`; a failed assertion when it is missing.
Json Expected(const Case& c) {
  const Json all = ExpectedTtk();
  if (!all.contains(c.file) || !all[c.file].contains(c.field)) {
    ADD_FAILURE() << c.file << " / " << c.field << " is not in expected-ttk.json of "
                  << io::testing::DataDir();
    return Json::object();
  }
  return all[c.file][c.field]["upstream"];
}

struct Loaded {
  std::shared_ptr<const Topology> topology;
  std::vector<SimplexId> order;
  std::vector<uint8_t> corners;  // InputCorners of the file's tetrahedra
  std::vector<double> scalars;   // by input vertex id
};

Loaded Load(const std::string& file, const std::string& field) {
  auto mesh = io::ReadMesh(io::testing::DataDir() + "/" + file);
  EXPECT_TRUE(mesh.ok()) << mesh.status();
  const int f = OkValue(SelectScalarField(*mesh, field));
  auto topo =
      OkValue(Topology::Build(*mesh, OctreeBlocks(mesh->points, {.bucket_capacity = 1000})));
  return {topo, VertexOrder(*topo, mesh->point_fields[f].values),
          OkValue(InputCorners(*topo, mesh->tetrahedra)), mesh->point_fields[f].values};
}

class MatchesTtk : public io::testing::DataTest {};

// One test per (file, field) of expected-ttk.json.
class MatchesTtkOn : public io::testing::DataTest, public ::testing::WithParamInterface<Case> {};

void PrintTo(const Case& c, std::ostream* out) { *out << c.file << " / " << c.field; }

std::string CaseName(const ::testing::TestParamInfo<Case>& info) {
  std::string name = info.param.file.substr(0, info.param.file.find('.')) + "_" + info.param.field;
  for (char& c : name) {
    if (!std::isalnum(static_cast<unsigned char>(c))) c = '_';
  }
  return name;
}

TEST_F(MatchesTtk, EveryExpectedDatasetIsTested) {
  const Json all = ExpectedTtk();
  ASSERT_FALSE(all.is_null()) << "expected-ttk.json not found in " << io::testing::DataDir();
  std::set<std::pair<std::string, std::string>> in_file, tested;
  for (const auto& [file, fields] : all.items()) {
    for (const auto& [field, entry] : fields.items()) in_file.emplace(file, field);
  }
  for (const Case& c : kCases) tested.emplace(c.file, c.field);
  EXPECT_EQ(in_file, tested);
}

// Runs `check(structure_label, run)` for every structure with 1, 2 and 3 consumers (actopo with
// 1 to 3 producers and two buffer ratios): results must not depend on any of them.
template <class Check>
void ForEveryStructureAndThreadCount(const Loaded& in, Prefetch prefetch, Check&& check) {
  auto explicit_structure = OkValue(ExplicitStructure::Build(in.topology, {}));
  for (int consumers : {1, 2, 3}) {
    const RunContext context{.consumers = consumers};
    const std::string c = " C=" + std::to_string(consumers);
    check("explicit" + c, *explicit_structure, context);
    CompactStructure compact(in.topology, {.cache_ratio = 0.1, .consumers = consumers});
    check("compact" + c, compact, context);
    const int producers = 1 + (consumers + 1) % 3;
    auto actopo =
        OkValue(ActopoStructure::Create(in.topology, {.consumers = consumers,
                                                      .producers = producers,
                                                      .buffer_ratio = consumers == 2 ? 0.05 : 0.2,
                                                      .prefetch = prefetch}));
    check("actopo P=" + std::to_string(producers) + c, *actopo, context);
  }
}

TEST_P(MatchesTtkOn, CriticalPointsAndDiscreteGradient) {
  const Case& c = GetParam();
  const Json expected = Expected(c);
  const Loaded in = Load(c.file, c.field);
  const Json& cp = expected["critical_points"];
  const Json& dg = expected["discrete_gradient"];
  ForEveryStructureAndThreadCount(
      in, Prefetch::kLinear,
      [&](const std::string& label, auto& structure, const RunContext& context) {
        SCOPED_TRACE(label);
        const CriticalPointsResult r = OkValue(RunCriticalPoints(structure, in.order, {}, context));
        EXPECT_EQ(r.counts[int(CriticalType::kMinimum)], cp["counts"]["minimum"].get<int64_t>());
        EXPECT_EQ(r.counts[int(CriticalType::kSaddle1)], cp["counts"]["saddle1"].get<int64_t>());
        EXPECT_EQ(r.counts[int(CriticalType::kSaddle2)], cp["counts"]["saddle2"].get<int64_t>());
        EXPECT_EQ(r.counts[int(CriticalType::kMaximum)], cp["counts"]["maximum"].get<int64_t>());
        EXPECT_EQ(r.counts[int(CriticalType::kDegenerate)],
                  cp["counts"]["degenerate"].get<int64_t>());
        EXPECT_EQ(r.VerticesDigest(), cp["vertices_sha256"].get<std::string>());

        const DiscreteGradientResult g =
            OkValue(RunDiscreteGradient(structure, in.order, context, GradientArrays::kAll));
        if constexpr (std::is_same_v<std::decay_t<decltype(structure)>, ExplicitStructure>) {
          testing::ExpectValidGradient(g, structure);  // the digests below cover the others
        }
        EXPECT_EQ(Json(g.critical_cells), dg["critical_cells"]);
        EXPECT_EQ(Json(g.pairs), dg["pairs_count"]);
        EXPECT_EQ(g.CriticalCellsDigest(*in.topology),
                  dg["critical_cells_sha256"].get<std::string>());
        EXPECT_EQ(g.PairsDigest(*in.topology), dg["pairs_sha256"].get<std::string>());
      });
}

TEST_P(MatchesTtkOn, MorseSmale) {
  const Case& c = GetParam();
  const Json expected = Expected(c);
  const Loaded in = Load(c.file, c.field);
  const Json& ms = expected["morse_smale"];
  // Linear: the default; morse_smale_test.cc covers the other prefetch modes.
  ForEveryStructureAndThreadCount(
      in, Prefetch::kLinear,
      [&](const std::string& label, auto& structure, const RunContext& context) {
        SCOPED_TRACE(label);
        const MorseSmaleResult r = OkValue(RunMorseSmale(structure, in.order, in.corners, context));
        testing::ExpectMorseSmaleEquals(r, ms);
      });
}

TEST_P(MatchesTtkOn, PersistenceDiagram) {
  const Case& c = GetParam();
  const Json expected = Expected(c);
  const Loaded in = Load(c.file, c.field);
  ASSERT_TRUE(expected.contains("persistence_diagram")) << c.file << " / " << c.field;
  const Json& pd = expected["persistence_diagram"];
  ForEveryStructureAndThreadCount(
      in, Prefetch::kLinear,
      [&](const std::string& label, auto& structure, const RunContext& context) {
        SCOPED_TRACE(label);
        const auto r = RunPersistenceDiagram(structure, in.order, in.scalars, context);
        ASSERT_TRUE(r.ok()) << r.status();
        EXPECT_EQ(int64_t(r->pairs.size()), pd["pairs"].get<int64_t>());
        Json counts = Json::object();
        for (int k = 0; k < 3; ++k) {
          if (r->finite[k] > 0) counts[std::to_string(k)] = r->finite[k];
          if (r->infinite[k] > 0) counts[std::to_string(k) + "_infinite"] = r->infinite[k];
        }
        EXPECT_EQ(counts, pd["counts_by_type"]);
        EXPECT_EQ(r->PairsDigest(), pd["pairs_sha256"].get<std::string>());
        EXPECT_NEAR(r->MaxPersistence(), pd["max_persistence"].get<double>(), 1e-9);
        if (pd.contains("lines")) {  // small diagrams: the pairs themselves, for a readable diff
          std::set<std::vector<int64_t>> got, want;
          for (const PersistencePair& p : r->pairs) {
            got.insert({p.type, p.birth, p.death, p.finite() ? 1 : 0});
          }
          for (const Json& line : pd["lines"]) want.insert(line.get<std::vector<int64_t>>());
          EXPECT_EQ(got, want);
        }
      });
}

// The tree's counts and digests against one entry of "merge_trees" (README of the data).
void ExpectTreeEquals(const TreeResult& r, const Json& expected) {
  EXPECT_EQ(int64_t(r.nodes.size()), expected["nodes"].get<int64_t>());
  EXPECT_EQ(int64_t(r.arcs.size()), expected["arcs"].get<int64_t>());
  Json types = Json::object();
  for (size_t t = 0; t < r.counts.size(); ++t) {
    if (r.counts[t] > 0) types[std::to_string(t)] = r.counts[t];
  }
  EXPECT_EQ(types, expected["critical_types"]);
  EXPECT_EQ(r.NodesDigest(), expected["nodes_sha256"].get<std::string>());
  EXPECT_EQ(r.ArcsDigest(), expected["arcs_sha256"].get<std::string>());
  EXPECT_EQ(r.SegmentationDigest(), expected["segmentation_sha256"].get<std::string>());
}

TEST_P(MatchesTtkOn, MergeTrees) {
  const Case& c = GetParam();
  const Json expected = Expected(c);
  ASSERT_TRUE(expected.contains("merge_trees")) << c.file << " / " << c.field;
  const Loaded in = Load(c.file, c.field);
  ForEveryStructureAndThreadCount(
      in, Prefetch::kLinear,
      [&](const std::string& label, auto& structure, const RunContext& context) {
        for (TreeType type : {TreeType::kJoin, TreeType::kSplit, TreeType::kContour}) {
          SCOPED_TRACE(label + " " + std::string(TreeTypeName(type)));
          const TreeResult r = OkValue(RunTree(structure, in.order, type, context));
          ExpectTreeEquals(r, expected["merge_trees"][std::string(TreeTypeName(type)) + "_tree"]);
        }
      });
}

INSTANTIATE_TEST_SUITE_P(ExpectedTtk, MatchesTtkOn, ::testing::ValuesIn(kCases), CaseName);

TEST_F(MatchesTtk, GradientInvariantsOnOtherMeshes) {
  for (const auto& [file, field] : {std::pair{"casting_tet.vtu", "eigenfunction4"},
                                    std::pair{"isabel02_s2_tet.vtu", "velocityMag"}}) {
    SCOPED_TRACE(file);
    const Loaded in = Load(file, field);
    auto explicit_structure = OkValue(ExplicitStructure::Build(in.topology, {}));
    const DiscreteGradientResult reference =
        OkValue(RunDiscreteGradient(*explicit_structure, in.order, {}, GradientArrays::kAll));
    testing::ExpectValidGradient(reference, *explicit_structure);
    auto actopo = OkValue(
        ActopoStructure::Create(in.topology, {.producers = 2, .prefetch = Prefetch::kAdaptive}));
    const DiscreteGradientResult r =
        OkValue(RunDiscreteGradient(*actopo, in.order, {}, GradientArrays::kAll));
    EXPECT_EQ(r.PairsDigest(*in.topology), reference.PairsDigest(*in.topology));
  }
}

}  // namespace
}  // namespace actopo
