// persistence-diagram: the pairs read back from the streamed arrays (JobResult::PersistencePairs)
// equal upstream TTK's (expected-ttk.json under the data directory), in both embeddings.
#include <algorithm>
#include <array>
#include <fstream>
#include <map>
#include <tuple>

#include "tests/testing/fixture.h"

namespace actopo::client::testing {
namespace {

using absl::StatusCode;
using Line = std::array<int64_t, 4>;  // type, birth vertex, death vertex, finite 1|0

constexpr char kDiagram[] = "persistence-diagram";
constexpr char kFingers[] = "viscousFingers001_s2_tet.vtu";

// The pairs as the lines of pairs_sha256, sorted as integer tuples (expected-ttk.json's "lines").
std::vector<Line> SortedLines(const std::vector<PersistencePair>& pairs) {
  std::vector<Line> lines;
  for (const PersistencePair& p : pairs) {
    lines.push_back({p.type, p.birth_vertex, p.death_vertex, p.finite ? 1 : 0});
  }
  std::sort(lines.begin(), lines.end());
  return lines;
}

// The summary's counts_by_type: "k" the finite pairs of type k, "k_infinite" the others; types
// without pairs left out.
nlohmann::json CountsByType(const std::vector<PersistencePair>& pairs) {
  std::map<std::string, int64_t> counts;
  for (const PersistencePair& p : pairs) {
    ++counts[std::to_string(p.type) + (p.finite ? "" : "_infinite")];
  }
  return counts;
}

double MaxPersistence(const std::vector<PersistencePair>& pairs) {
  double best = 0;
  for (const PersistencePair& p : pairs) best = std::max(best, p.persistence);
  return best;
}

// What holds for any diagram: the pairs come in birth order, a pair's death is its birth plus
// its persistence, and every critical cell of the gradient is in exactly one pair
// (SEMANTICS.md: c0 = f0 + i0, c1 = f0 + f1 + i1, c2 = f1 + f2 + i2, c3 = f2).
void ExpectConsistent(const std::vector<PersistencePair>& pairs, const nlohmann::json& summary) {
  std::array<int64_t, 3> finite{}, infinite{};
  for (size_t i = 0; i < pairs.size(); ++i) {
    const PersistencePair& p = pairs[i];
    if (i > 0) {
      EXPECT_LE(pairs[i - 1].birth, p.birth) << "pair " << i;
    }
    EXPECT_GE(p.persistence, 0) << "pair " << i;
    EXPECT_EQ(p.death - p.birth, p.persistence) << "pair " << i;
    ++(p.finite ? finite : infinite)[size_t(p.type)];
  }
  EXPECT_EQ(summary["pairs"].get<int64_t>(), int64_t(pairs.size()));
  EXPECT_EQ(summary["critical_cells"].get<std::vector<int64_t>>(),
            (std::vector<int64_t>{finite[0] + infinite[0], finite[0] + finite[1] + infinite[1],
                                  finite[1] + finite[2] + infinite[2], finite[2]}));
}

// fertility height is small enough for expected-ttk.json to list its pairs: all equal TTK's.
TEST_F(ServerTest, FertilityHeightPairsEqualTtks) {
  const nlohmann::json ttk = TtkReference("fertility_tet.vtu", "height", "persistence_diagram");
  ASSERT_TRUE(ttk.contains("lines"));
  const std::string session =
      Open(Fertility(), {.scalar = "height", .structure = Structure::kCompact});
  absl::StatusOr<JobResult> result = client().RunJob(session, kDiagram, {}, {.digests = true});
  ASSERT_OK(result);
  EXPECT_EQ(result->algorithm, kDiagram);
  absl::StatusOr<std::vector<PersistencePair>> pairs = result->PersistencePairs();
  ASSERT_OK(pairs);

  EXPECT_EQ(int64_t(pairs->size()), ttk["pairs"].get<int64_t>());
  EXPECT_EQ(SortedLines(*pairs), ttk["lines"].get<std::vector<Line>>());
  EXPECT_EQ(CountsByType(*pairs), ttk["counts_by_type"]);
  // Both are the difference of the same two field values in double precision.
  EXPECT_EQ(MaxPersistence(*pairs), ttk["max_persistence"].get<double>());
  const nlohmann::json summary = nlohmann::json::parse(result->summary_json);
  EXPECT_EQ(summary["pairs_sha256"], ttk["pairs_sha256"]);
  ExpectConsistent(*pairs, summary);
}

// viscousFingers density has pairs of every type; expected-ttk.json gives their counts.
TEST_F(ServerTest, ViscousFingersPairsEqualTtksInBothEmbeddings) {
  const nlohmann::json ttk = TtkReference(kFingers, "density", "persistence_diagram");
  absl::StatusOr<MeshInfo> mesh = client().LoadMesh(kFingers);
  ASSERT_OK(mesh);
  meshes_.push_back(mesh->mesh_id);
  const std::string session = Open(mesh->mesh_id, {.scalar = "density", .consumers = 2});
  absl::StatusOr<JobResult> plane = client().RunJob(session, kDiagram, {}, {.digests = true});
  ASSERT_OK(plane);
  absl::StatusOr<std::vector<PersistencePair>> pairs = plane->PersistencePairs();
  ASSERT_OK(pairs);

  const int64_t n = ttk["pairs"].get<int64_t>();
  EXPECT_EQ(int64_t(pairs->size()), n);
  EXPECT_EQ(CountsByType(*pairs), ttk["counts_by_type"]);
  EXPECT_EQ(MaxPersistence(*pairs), ttk["max_persistence"].get<double>());
  const nlohmann::json summary = nlohmann::json::parse(plane->summary_json);
  EXPECT_EQ(summary["pairs_sha256"], ttk["pairs_sha256"]);
  ExpectConsistent(*pairs, summary);
  // On the wire, TTK's diagonal is one more line, which the pairs leave out.
  absl::StatusOr<std::vector<int32_t>> identifiers = plane->Get<int32_t>("diagram/PairIdentifier");
  ASSERT_OK(identifiers);
  ASSERT_EQ(int64_t(identifiers->size()), n + 1);
  EXPECT_EQ(identifiers->back(), -1);
  EXPECT_EQ(plane->Find("diagram/Offsets")->size(), n + 2);
  EXPECT_EQ(plane->Find("diagram/Points")->shape, (std::vector<int64_t>{2 * n, 3}));

  // Embedded in the domain: the same pairs, points at the vertices, no diagonal.
  const std::string explicit_session =
      Open(mesh->mesh_id, {.scalar = "density", .structure = Structure::kExplicit});
  absl::StatusOr<JobResult> domain =
      client().RunJob(explicit_session, kDiagram, {{"embedding", "domain"}});
  ASSERT_OK(domain);
  absl::StatusOr<std::vector<PersistencePair>> at_vertices = domain->PersistencePairs();
  ASSERT_OK(at_vertices);
  EXPECT_EQ(domain->Find("diagram/PairIdentifier")->size(), n);
  EXPECT_EQ(domain->Find("diagram/Offsets")->size(), n + 1);
  ASSERT_EQ(at_vertices->size(), pairs->size());
  for (size_t i = 0; i < pairs->size(); ++i) {
    const PersistencePair &a = (*pairs)[i], &b = (*at_vertices)[i];
    EXPECT_EQ(std::tie(a.type, a.birth_vertex, a.death_vertex, a.finite, a.birth, a.persistence),
              std::tie(b.type, b.birth_vertex, b.death_vertex, b.finite, b.birth, b.persistence))
        << "pair " << i;
    EXPECT_DOUBLE_EQ(a.death, b.death) << "pair " << i;  // b's is birth + persistence
  }
}

TEST_F(ServerTest, PersistencePairsNeedADiagramsArrays) {
  const std::string session = Open(LoadSample("jittered:8"), {.structure = Structure::kCompact});
  absl::StatusOr<JobResult> lean =
      client().RunJob(session, kDiagram, {}, {.include_arrays = false});
  ASSERT_OK(lean);
  EXPECT_GT(nlohmann::json::parse(lean->summary_json)["pairs"].get<int64_t>(), 0);
  EXPECT_TRUE(HasError(lean->PersistencePairs(), StatusCode::kNotFound, "include_arrays"));
  absl::StatusOr<JobResult> points = client().RunJob(session, "critical-points");
  ASSERT_OK(points);
  EXPECT_TRUE(HasError(points->PersistencePairs(), StatusCode::kNotFound,
                       "'diagram/PairIdentifier' not found"));
  EXPECT_TRUE(HasError(client().RunJob(session, kDiagram, {{"embedding", "x"}}),
                       StatusCode::kInvalidArgument,
                       "parameters.embedding: unknown value 'x'; available: diagram, domain"));
}

}  // namespace
}  // namespace actopo::client::testing
