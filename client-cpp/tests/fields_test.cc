// Fields added to a loaded mesh (AddFields) and deleted (DeleteField): a job on an added field
// equals one on the same values uploaded with the mesh, float32 values and time values arrive,
// every rejection keeps its code and names what was wrong, and the mesh stays as it was.
#include <cmath>
#include <limits>

#include "tests/testing/fixture.h"
#include "tests/testing/lattice.h"

namespace actopo::client::testing {
namespace {

using absl::StatusCode;

class FieldsTest : public ServerTest {
 protected:
  // A 12^3 lattice uploaded with "wave", a field of several extrema per axis (so its diagram
  // has pairs of every type), whose values the test knows; returns the mesh id.
  std::string UploadWave() {
    for (size_t v = 0; v < size_t(lattice_.vertices()); ++v) {
      const double x = lattice_.points[3 * v], y = lattice_.points[3 * v + 1],
                   z = lattice_.points[3 * v + 2];
      wave_.push_back(std::sin(7 * x + 1) * std::cos(5 * y) + std::sin(6 * z + 2 * x) +
                      1e-3 * lattice_.height[v]);
    }
    absl::StatusOr<MeshInfo> mesh = client().UploadMesh(lattice_.points, lattice_.tetrahedra32,
                                                        {{"wave", wave_}}, {.name = "wave"});
    EXPECT_TRUE(mesh.ok()) << mesh.status();
    if (!mesh.ok()) return "";
    meshes_.push_back(mesh->mesh_id);
    return mesh->mesh_id;
  }

  // A job of `algorithm` on field `scalar` of `mesh`, with digests, as parsed JSON.
  nlohmann::json Summary(const std::string& mesh, const std::string& scalar,
                         const std::string& algorithm) {
    const std::string session = Open(mesh, {.scalar = scalar, .structure = Structure::kCompact});
    absl::StatusOr<JobResult> result =
        client().RunJob(session, algorithm, {}, {.include_arrays = false, .digests = true});
    EXPECT_TRUE(result.ok()) << scalar << ": " << result.status();
    return result.ok() ? nlohmann::json::parse(result->summary_json) : nlohmann::json();
  }

  static std::vector<std::string> Names(const MeshInfo& mesh) {
    std::vector<std::string> names;
    for (const FieldInfo& f : mesh.fields) names.push_back(f.name);
    return names;
  }

  Lattice lattice_{12};
  std::vector<double> wave_;
};

TEST_F(FieldsTest, AnAddedFieldEqualsTheSameValuesUploaded) {
  const std::string mesh = UploadWave();
  ASSERT_FALSE(mesh.empty());
  std::vector<double> doubled;
  for (double v : wave_) doubled.push_back(2 * v);
  // Float32 values, and the same values widened: the server takes both to float64 exactly.
  std::vector<float> narrow(wave_.begin(), wave_.end());
  const std::vector<double> widened(narrow.begin(), narrow.end());
  // 999-byte chunks: values straddle chunks, and chunks straddle fields of either width.
  absl::StatusOr<MeshInfo> added =
      client().AddFields(mesh,
                         {{.name = "wave_again", .values = wave_},
                          {.name = "doubled", .values = doubled, .time = 0.25},
                          {.name = "narrow", .values = narrow, .time = 0.5},
                          {.name = "widened", .values = widened}},
                         {.chunk_bytes = 999});
  ASSERT_OK(added);
  EXPECT_EQ(Names(*added),
            (std::vector<std::string>{"wave", "wave_again", "doubled", "narrow", "widened"}));
  const FieldInfo& narrow_info = added->fields[3];
  EXPECT_EQ(narrow_info.dtype, DataType::kFloat32);
  EXPECT_EQ(narrow_info.min, double(*std::min_element(narrow.begin(), narrow.end())));
  EXPECT_EQ(narrow_info.max, double(*std::max_element(narrow.begin(), narrow.end())));
  EXPECT_EQ(narrow_info.time, 0.5);
  EXPECT_EQ(added->fields[2].dtype, DataType::kFloat64);
  EXPECT_EQ(added->fields[2].time, 0.25);
  EXPECT_EQ(added->fields[1].time, std::nullopt);
  EXPECT_EQ(added->fields[0].time, std::nullopt);
  EXPECT_EQ(added->fields[2].max, 2 * added->fields[0].max);
  absl::StatusOr<MeshInfo> described = client().GetMesh(mesh);
  ASSERT_OK(described);
  EXPECT_EQ(Names(*described), Names(*added));
  EXPECT_EQ(described->fields[3].time, 0.5);

  for (const char* algorithm : {"critical-points", "persistence-diagram"}) {
    SCOPED_TRACE(algorithm);
    const nlohmann::json uploaded = Summary(mesh, "wave", algorithm);
    EXPECT_EQ(Summary(mesh, "wave_again", algorithm), uploaded);
    EXPECT_EQ(Summary(mesh, "narrow", algorithm), Summary(mesh, "widened", algorithm));
    // Doubling keeps the vertex order, so the same critical vertices and pairs.
    const nlohmann::json doubled_summary = Summary(mesh, "doubled", algorithm);
    if (std::string(algorithm) == "critical-points") {
      EXPECT_EQ(doubled_summary, uploaded);
    } else {
      ASSERT_TRUE(uploaded.contains("pairs_sha256")) << uploaded.dump();
      EXPECT_EQ(doubled_summary["pairs_sha256"], uploaded["pairs_sha256"]);
      EXPECT_EQ(doubled_summary["pairs"], uploaded["pairs"]);
      EXPECT_GT(uploaded["pairs"].get<int64_t>(), 10);
      EXPECT_DOUBLE_EQ(doubled_summary["max_persistence"].get<double>(),
                       2 * uploaded["max_persistence"].get<double>());
    }
  }

  // One field alone, checked against no digest at all.
  absl::StatusOr<MeshInfo> one =
      client().AddField(mesh, {.name = "unchecked", .values = wave_}, {.sha256 = ""});
  ASSERT_OK(one);
  EXPECT_EQ(one->fields.back().name, "unchecked");
}

TEST_F(FieldsTest, EveryRejectionHasItsCodeAndTheMeshStaysAsItWas) {
  const std::string mesh = UploadWave();
  ASSERT_FALSE(mesh.empty());
  const std::vector<double> good = wave_;
  const std::span<const double> short_values = std::span(wave_).first(wave_.size() - 1);
  std::vector<double> nan = wave_;
  nan[17] = std::numeric_limits<double>::quiet_NaN();
  std::vector<float> infinite(wave_.begin(), wave_.end());
  infinite[5] = std::numeric_limits<float>::infinity();

  EXPECT_TRUE(HasError(client().AddField("mesh-guess", {.name = "f", .values = good}),
                       StatusCode::kNotFound, "mesh_id: no mesh 'mesh-guess'"));
  // A valid field before the bad one: all or nothing.
  EXPECT_TRUE(HasError(
      client().AddFields(mesh,
                         {{.name = "fine", .values = good}, {.name = "wave", .values = good}}),
      StatusCode::kAlreadyExists, "header.fields[1].name: mesh '" + mesh + "' has a field 'wave'"));
  // The stream ends inside the field: the message names it and how far its values went.
  EXPECT_TRUE(HasError(client().AddField(mesh, {.name = "short", .values = short_values}),
                       StatusCode::kInvalidArgument,
                       absl::StrCat("in fields[0] 'short' after ", short_values.size(), " of its ",
                                    wave_.size(), " values (one per vertex of the mesh)")));
  EXPECT_TRUE(HasError(
      client().AddFields(mesh, {{.name = "fine", .values = good}, {.name = "nan", .values = nan}}),
      StatusCode::kInvalidArgument, "fields[1] 'nan': vertex 17 has value nan"));
  EXPECT_TRUE(HasError(client().AddField(mesh, {.name = "infinite", .values = infinite}),
                       StatusCode::kInvalidArgument,
                       "fields[0] 'infinite': vertex 5 has value inf"));
  EXPECT_TRUE(HasError(
      client().AddField(mesh, {.name = "sum", .values = good}, {.sha256 = std::string(64, '0')}),
      StatusCode::kDataLoss, "header.sha256: the values hash to "));
  // Fields of different lengths would shift into each other: the client refuses them.
  EXPECT_TRUE(HasError(client().AddFields(mesh, {{.name = "fine", .values = good},
                                                 {.name = "short", .values = short_values}}),
                       StatusCode::kInvalidArgument,
                       absl::StrCat("fields[1] 'short': ", wave_.size() - 1,
                                    " values but fields[0] 'fine' has ", wave_.size())));

  absl::StatusOr<MeshInfo> after = client().GetMesh(mesh);
  ASSERT_OK(after);
  EXPECT_EQ(Names(*after), std::vector<std::string>{"wave"});
  // What the refused calls reserved is free again: the fields they named can be added now.
  EXPECT_OK(client().AddFields(mesh, {{.name = "fine", .values = good},
                                      {.name = "sum", .values = good},
                                      {.name = "nan", .values = good}}));
}

// Past the memory budget: RESOURCE_EXHAUSTED naming the field that did not fit, nothing added,
// and what the refused call reserved free again for the next.
TEST_F(ServerTest, AddedFieldsCountAgainstTheMemoryBudget) {
  auto server = ServerProcess::Start(ServerBinary(), DataDir(), {"--memory-budget-mib", "1"});
  ASSERT_OK(server);
  auto connected = Client::Connect((*server)->target());
  ASSERT_OK(connected);
  Client& c = **connected;
  absl::StatusOr<MeshInfo> mesh = c.LoadMesh("sample:jittered:12");
  ASSERT_OK(mesh);
  const std::vector<double> values(size_t(mesh->vertices), 1.5);  // 13.5 KiB a field
  std::vector<FieldValues> many;
  for (int i = 0; i < 100; ++i) {
    many.push_back({.name = absl::StrCat("f", i), .values = values});
  }
  const absl::Status refused = c.AddFields(mesh->mesh_id, many).status();
  EXPECT_TRUE(HasError(refused, StatusCode::kResourceExhausted, "field 'f"));
  EXPECT_TRUE(HasError(refused, StatusCode::kResourceExhausted,
                       "' of mesh '" + mesh->mesh_id + "' needs about"));
  absl::StatusOr<MeshInfo> after = c.GetMesh(mesh->mesh_id);
  ASSERT_OK(after);
  EXPECT_EQ(after->fields.size(), mesh->fields.size());
  many.resize(10);
  absl::StatusOr<MeshInfo> fits = c.AddFields(mesh->mesh_id, many);
  ASSERT_OK(fits);
  EXPECT_EQ(fits->fields.size(), mesh->fields.size() + 10);
}

TEST_F(FieldsTest, DeleteField) {
  const std::string mesh = UploadWave();
  ASSERT_FALSE(mesh.empty());
  std::vector<double> negated;
  for (double v : wave_) negated.push_back(-v);
  ASSERT_OK(client().AddField(mesh, {.name = "negated", .values = negated}));
  // A session on the field keeps it after its deletion.
  const std::string session = Open(mesh, {.scalar = "negated", .structure = Structure::kCompact});
  absl::StatusOr<MeshInfo> deleted = client().DeleteField(mesh, "negated");
  ASSERT_OK(deleted);
  EXPECT_EQ(Names(*deleted), std::vector<std::string>{"wave"});
  absl::StatusOr<JobResult> still = client().RunJob(session, "critical-points");
  ASSERT_OK(still);
  EXPECT_FALSE(still->arrays.empty());
  EXPECT_TRUE(HasError(client().DeleteField(mesh, "negated"), StatusCode::kNotFound,
                       "name: the mesh has no field 'negated'; its fields: 'wave'"));
  EXPECT_TRUE(HasError(client().DeleteField("mesh-guess", "wave"), StatusCode::kNotFound,
                       "mesh_id: no mesh 'mesh-guess'"));
  EXPECT_TRUE(HasError(client().OpenSession(mesh, {.scalar = "negated"}), StatusCode::kNotFound,
                       "negated"));
  // The name is free again.
  absl::StatusOr<MeshInfo> again = client().AddField(mesh, {.name = "negated", .values = negated});
  ASSERT_OK(again);
  EXPECT_EQ(Names(*again), (std::vector<std::string>{"wave", "negated"}));
}

}  // namespace
}  // namespace actopo::client::testing
