// topological-simplification and the Morse-Smale complex of the simplified field against
// upstream TTK's filters chained the same way (tests/ttk_reference/simplification-ttk.json, made
// by simplification_reference.py there): the simplified values and order value for value, and
// the complex's counts and segmentation digests; on every structure.
#include <cctype>
#include <fstream>
#include <set>

#include "gtest/gtest.h"
#include "nlohmann/json.hpp"
#include "server/algorithms/morse_smale.h"
#include "server/algorithms/topological_simplification.h"
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

struct Case {
  std::string file, field, fraction;
  bool legacy = false;  // TTK's legacy backend ("legacy_results") instead of LTS ("results")
};
// Listed, not read from the file, so the tests exist however ctest lists them;
// EveryReferenceIsTested keeps the list equal to the file.
const Case kCases[] = {
    {"manifoldCheck0_tet.vtu", "height", "0.01"},
    {"manifoldCheck0_tet.vtu", "height", "0.05"},
    {"fertility_tet.vtu", "eigenfunction4", "0.01"},
    {"fertility_tet.vtu", "eigenfunction4", "0.05"},
    {"fertility_tet.vtu", "height", "0.01"},
    {"fertility_tet.vtu", "height", "0.05"},
    {"viscousFingers001_s2_tet.vtu", "density", "0.01"},
    {"viscousFingers001_s2_tet.vtu", "density", "0.05"},
    {"isabel02_s2_tet.vtu", "velocityMag", "0.01"},
    {"isabel02_s2_tet.vtu", "velocityMag", "0.05"},
    {"manifoldCheck0_tet.vtu", "height", "0.01", true},
    {"manifoldCheck0_tet.vtu", "height", "0.05", true},
    {"fertility_tet.vtu", "eigenfunction4", "0.01", true},
    {"fertility_tet.vtu", "eigenfunction4", "0.05", true},
    {"fertility_tet.vtu", "height", "0.01", true},
    {"fertility_tet.vtu", "height", "0.05", true},
    {"viscousFingers001_s2_tet.vtu", "density", "0.01", true},
    {"viscousFingers001_s2_tet.vtu", "density", "0.05", true},
};

Json References() {
  std::ifstream in(std::string(ACTOPO_TTK_REFERENCE_DIR) + "/simplification-ttk.json");
  return in ? Json::parse(in) : Json();
}

void PrintTo(const Case& c, std::ostream* out) {
  *out << c.file << " / " << c.field << " / " << c.fraction << (c.legacy ? " / legacy" : "");
}

std::string CaseName(const ::testing::TestParamInfo<Case>& info) {
  std::string name = info.param.file.substr(0, info.param.file.find('.')) + "_" + info.param.field +
                     "_" + info.param.fraction + (info.param.legacy ? "_legacy" : "");
  for (char& c : name) {
    if (!std::isalnum(static_cast<unsigned char>(c))) c = '_';
  }
  return name;
}

class SimplificationMatchesTtk : public io::testing::DataTest,
                                 public ::testing::WithParamInterface<Case> {};

TEST(SimplificationReferences, EveryReferenceIsTested) {
  const Json all = References();
  ASSERT_FALSE(all.is_null()) << "simplification-ttk.json not found in "
                              << ACTOPO_TTK_REFERENCE_DIR;
  std::set<std::tuple<std::string, std::string, std::string, bool>> in_file, tested;
  for (const bool legacy : {false, true}) {
    for (const auto& [file, fields] : all[legacy ? "legacy_results" : "results"].items()) {
      for (const auto& [field, fractions] : fields.items()) {
        for (const auto& [fraction, entry] : fractions.items()) {
          in_file.emplace(file, field, fraction, legacy);
        }
      }
    }
  }
  for (const Case& c : kCases) tested.emplace(c.file, c.field, c.fraction, c.legacy);
  EXPECT_EQ(in_file, tested);
}

TEST_P(SimplificationMatchesTtk, ValuesOrderAndMorseSmale) {
  const Case& c = GetParam();
  const Json all = References()[c.legacy ? "legacy_results" : "results"];
  ASSERT_TRUE(all.contains(c.file) && all[c.file].contains(c.field) &&
              all[c.file][c.field].contains(c.fraction));
  const Json& expected = all[c.file][c.field][c.fraction];
  auto mesh = io::ReadMesh(io::testing::DataDir() + "/" + c.file);
  ASSERT_TRUE(mesh.ok()) << mesh.status();
  const int f = OkValue(SelectScalarField(*mesh, c.field));
  const std::vector<double>& scalars = mesh->point_fields[f].values;
  auto topo =
      OkValue(Topology::Build(*mesh, OctreeBlocks(mesh->points, {.bucket_capacity = 1000})));
  const std::vector<SimplexId> order = VertexOrder(*topo, scalars);
  const SimplificationOptions options{
      .threshold = std::stod(c.fraction), .relative = true, .legacy = c.legacy};

  const auto check = [&](const std::string& label, auto& structure, const RunContext& context) {
    SCOPED_TRACE(label);
    const auto r = RunTopologicalSimplification(structure, order, scalars, options, context);
    ASSERT_TRUE(r.ok()) << r.status();
    EXPECT_NEAR(r->threshold, expected["threshold"].get<double>(), 1e-12);
    EXPECT_EQ(r->stats.kept_pairs, expected["kept_pairs"].get<int64_t>());
    int64_t changed = 0;
    for (size_t v = 0; v < scalars.size(); ++v) changed += r->scalars[v] != scalars[v];
    EXPECT_EQ(changed, expected["changed_values"].get<int64_t>());
    if (expected.contains("changes")) {
      for (const Json& change : expected["changes"]) {
        const auto v = change[0].get<size_t>();
        EXPECT_EQ(r->scalars[v], change[1].get<double>()) << "vertex " << v;
      }
    }
    EXPECT_EQ(r->ScalarsDigest(), expected["scalars_sha256"].get<std::string>());
    EXPECT_EQ(r->OrderDigest(), expected["order_sha256"].get<std::string>());
    const auto ms =
        RunMorseSmale(structure, r->internal_order,
                      OkValue(InputCorners(structure.topology(), mesh->tetrahedra)), context);
    ASSERT_TRUE(ms.ok()) << ms.status();
    testing::ExpectMorseSmaleEquals(*ms, expected["morse_smale"]);
  };
  auto explicit_structure = OkValue(ExplicitStructure::Build(topo, {}));
  for (int consumers : {1, 2}) {
    const RunContext context{.consumers = consumers};
    const std::string n = " C=" + std::to_string(consumers);
    check("explicit" + n, *explicit_structure, context);
    CompactStructure compact(topo, {.cache_ratio = 0.1, .consumers = consumers});
    check("compact" + n, compact, context);
    auto actopo = OkValue(ActopoStructure::Create(topo, {.consumers = consumers, .producers = 2}));
    check("actopo" + n, *actopo, context);
  }
}

INSTANTIATE_TEST_SUITE_P(TtkReference, SimplificationMatchesTtk, ::testing::ValuesIn(kCases),
                         CaseName);

}  // namespace
}  // namespace actopo
