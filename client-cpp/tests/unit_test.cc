// What the client does without a server: arrays, names, statistics, tokens, argument checks.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <iostream>
#include <thread>
#include <tuple>

#include "absl/strings/str_cat.h"
#include "actopo/client.h"

namespace actopo::client {
namespace {

// The example of the header's overview, word for word, so that it keeps compiling (never run: it
// needs a server on port 50051).
[[maybe_unused]] absl::Status HeaderOverviewExample() {
  absl::StatusOr<std::unique_ptr<actopo::client::Client>> client =
      actopo::client::Client::Connect("127.0.0.1:50051");
  if (!client.ok()) return client.status();
  absl::StatusOr<actopo::client::MeshInfo> mesh = (*client)->LoadMesh("sample:jittered:20");
  if (!mesh.ok()) return mesh.status();
  absl::StatusOr<actopo::client::SessionInfo> session =
      (*client)->OpenSession(mesh->mesh_id, {.structure = actopo::client::Structure::kCompact});
  if (!session.ok()) return session.status();
  absl::StatusOr<std::vector<int64_t>> star =
      (*client)->Relation(session->session_id, "vertex_star", 7);  // tetrahedra around 7
  absl::StatusOr<actopo::client::JobResult> result =
      (*client)->RunJob(session->session_id, "critical-points");
  if (result.ok()) std::cout << result->summary_json << "\n";  // {"counts": {...}, ...}
  return absl::OkStatus();
}

// The examples of README.md's "Fields and series", so that they keep compiling (never run).
[[maybe_unused]] absl::Status ReadmeSeriesExamples(Client* client, const std::string& mesh_id,
                                                   const std::string& session_id,
                                                   const std::vector<double>& wave) {
  const auto PressureAt = [&](int) { return std::vector<float>(wave.begin(), wave.end()); };
  const std::vector<double> tripled = wave;
  {
    absl::StatusOr<actopo::client::MeshInfo> series = client->LoadSeries(
        {"isabel_series_s2/isabel_02_s2_tet.vtu", "isabel_series_s2/isabel_03_s2_tet.vtu"},
        {2.0, 3.0});                           // velocityMag_0 at time 2, velocityMag_1 at time 3
    if (!series.ok()) return series.status();  // e.g. NOT_FOUND: files.paths[1]: ...
  }
  {
    std::vector<double> doubled(wave.size());
    for (size_t v = 0; v < wave.size(); ++v) doubled[v] = 2 * wave[v];
    std::vector<float> step7 = PressureAt(7);  // one per vertex
    absl::StatusOr<actopo::client::MeshInfo> mesh =
        client->AddFields(mesh_id, {{.name = "doubled", .values = doubled},
                                    {.name = "pressure_07", .values = step7, .time = 0.7}});
    if (!mesh.ok()) return mesh.status();  // e.g. ALREADY_EXISTS: header.fields[0].name: ...
    absl::StatusOr<actopo::client::MeshInfo> one =
        client->AddField(mesh_id, {.name = "tripled", .values = tripled});
  }
  { absl::StatusOr<actopo::client::MeshInfo> mesh = client->DeleteField(mesh_id, "doubled"); }
  {
    absl::StatusOr<actopo::client::JobResult> result = client->RunJob(
        session_id, "critical-points", {},
        {.fields = {"height", "scalar"}, .on_field = [](const actopo::client::FieldResult& f) {
           std::cerr << f.field << " done\n";
         }});
    if (!result.ok()) return result.status();
    for (const actopo::client::FieldResult& f : result->fields) {
      absl::StatusOr<std::vector<int8_t>> types = f.Get<int8_t>("critical_points/CriticalType");
      if (types.ok()) std::cout << f.field << ": " << types->size() << " critical points\n";
    }
  }
  {
    absl::StatusOr<actopo::client::DistanceMatrix> matrix =
        client->DiagramDistances(session_id, {{"relative_threshold", "0.01"}});
    if (!matrix.ok()) return matrix.status();
    for (size_t i = 0; i < matrix->size(); ++i) {
      for (size_t j = 0; j < matrix->size(); ++j) std::cout << matrix->Wasserstein(i, j) << " ";
      std::cout << "\n";
    }
  }
  {
    absl::StatusOr<actopo::client::MeshInfo> series =
        client->LoadMesh("isabel_series_s2/isabel_series.pvd");  // FieldInfo::time 2, 3, 4, 5
    if (!series.ok()) return series.status();
    absl::StatusOr<actopo::client::SessionInfo> session = client->OpenSession(series->mesh_id);
    if (!session.ok()) return session.status();
    absl::StatusOr<actopo::client::JobResult> result =
        client->RunJob(session->session_id, "tracking", {}, {.all_fields = true});
    if (!result.ok()) return result.status();
    absl::StatusOr<actopo::client::TrackingSummary> tracking = result->Tracking();
    absl::StatusOr<std::vector<double>> cost = result->Get<double>("tracking/Cost");
    if (tracking.ok()) std::cout << tracking->trajectories << " trajectories\n";
  }
  return absl::OkStatus();
}

// The examples of ResultArrays::Tree in the header and README.md, so that they keep compiling
// (never run).
[[maybe_unused]] absl::Status TreeExamples(Client* client, const std::string& session_id) {
  {
    absl::StatusOr<actopo::client::JobResult> result =
        client->RunJob(session_id, "merge-tree", {{"tree", "split"}});
    if (!result.ok()) return result.status();
    absl::StatusOr<actopo::client::ScalarTree> tree = result->Tree();
    if (!tree.ok()) return tree.status();
    for (const actopo::client::ScalarTree::Arc& a : tree->arcs) {
      const actopo::client::ScalarTree::Node& down = tree->nodes[size_t(a.down_node)];
      std::cout << down.vertex << " (" << down.scalar << "): " << a.region_size << " vertices\n";
    }
  }
  {
    absl::StatusOr<JobResult> result = client->RunJob(session_id, "contour-tree");
    if (!result.ok()) return result.status();
    absl::StatusOr<ScalarTree> tree = result->Tree();
    for (const ScalarTree::Arc& a : tree->arcs) {
      std::cout << tree->nodes[a.down_node].vertex << " -> " << tree->nodes[a.up_node].vertex
                << ": " << a.region_size << " vertices\n";
    }
  }
  return absl::OkStatus();
}

// The examples of UploadFile in the header and in README.md's "Uploading a mesh file", so that
// they keep compiling (never run).
[[maybe_unused]] absl::Status UploadFileExamples(Client* client) {
  {
    auto mesh = client->UploadFile("/data/wavelet128.vtu",
                                   {.progress = [](const actopo::client::UploadFileProgress& p) {
                                     std::cerr << p.phase << " " << int(100 * p.fraction) << "%\r";
                                   }});
    if (mesh.ok()) std::cout << mesh->vertices << " vertices\n";  // source "upload:..."
  }
  {
    actopo::client::UploadFileOptions options;
    options.progress = [](const actopo::client::UploadFileProgress& p) {
      std::cerr << p.phase << " " << int(100 * p.fraction) << "%, " << p.sent_bytes
                << " bytes sent\r";
    };
    absl::StatusOr<actopo::client::MeshInfo> mesh = client->UploadFile("wavelet128.vtu", options);
    if (!mesh.ok()) return mesh.status();  // e.g. UNAVAILABLE: ... (gave up after 5 resumptions
    std::cout << mesh->source << ": " << mesh->vertices << " vertices\n";  // upload:wavelet128.vtu
  }
  return absl::OkStatus();
}

template <class T>
Array MakeArray(const std::string& name, std::vector<T> values, std::vector<int64_t> shape) {
  Array a{.name = name, .dtype = kDataTypeOf<T>, .shape = std::move(shape)};
  a.data.assign(reinterpret_cast<const char*>(values.data()), values.size() * sizeof(T));
  return a;
}

TEST(ArrayTest, TypedAccessChecksTheDtypeAndSize) {
  const Array a = MakeArray<int32_t>("critical_points/CellId", {3, -1, 7, 9}, {2, 2});
  EXPECT_EQ(a.size(), 4);
  absl::StatusOr<std::vector<int32_t>> values = a.As<int32_t>();
  ASSERT_TRUE(values.ok()) << values.status();
  EXPECT_EQ(*values, (std::vector<int32_t>{3, -1, 7, 9}));
  absl::StatusOr<std::vector<int64_t>> wrong = a.As<int64_t>();
  EXPECT_EQ(wrong.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_NE(wrong.status().message().find("int32"), std::string::npos) << wrong.status();
  EXPECT_EQ(*a.ToInt64(), (std::vector<int64_t>{3, -1, 7, 9}));
  EXPECT_EQ(a.ToDouble(), (std::vector<double>{3, -1, 7, 9}));

  Array ragged = a;
  ragged.data.pop_back();
  EXPECT_EQ(ragged.As<int32_t>().status().code(), absl::StatusCode::kInvalidArgument);
}

TEST(ArrayTest, ConversionsCoverEveryDtype) {
  EXPECT_EQ(MakeArray<int8_t>("a", {-2, 5}, {2}).ToDouble(), (std::vector<double>{-2, 5}));
  EXPECT_EQ(MakeArray<uint8_t>("a", {200, 5}, {2}).ToDouble(), (std::vector<double>{200, 5}));
  EXPECT_EQ(MakeArray<float>("a", {0.5f}, {1}).ToDouble(), (std::vector<double>{0.5}));
  EXPECT_EQ(*MakeArray<int64_t>("a", {int64_t{1} << 40}, {1}).ToInt64(),
            (std::vector<int64_t>{int64_t{1} << 40}));
  EXPECT_EQ(MakeArray<double>("a", {1.5}, {1}).ToInt64().status().code(),
            absl::StatusCode::kInvalidArgument);
  EXPECT_EQ(DataTypeName(DataType::kFloat64), "float64");
  EXPECT_EQ(DataTypeSize(DataType::kInt8), 1u);
  EXPECT_EQ(DataTypeSize(DataType::kUnspecified), 0u);
}

TEST(JobResultTest, GetFindsArraysByName) {
  JobResult result;
  result.arrays["critical_points/CriticalType"] =
      MakeArray<int8_t>("critical_points/CriticalType", {0, 3}, {2});
  EXPECT_EQ(*result.Get<int8_t>("critical_points/CriticalType"), (std::vector<int8_t>{0, 3}));
  EXPECT_EQ(result.Get<int8_t>("critical_points/Nope").status().code(),
            absl::StatusCode::kNotFound);
  EXPECT_EQ(result.Find("x"), nullptr);
}

// The diagram/ arrays a persistence-diagram job streams for `pairs` (TTK's grid): two points and
// a line per pair, then TTK's diagonal unless embedded in the domain, where the points are the
// vertices' positions (here (vertex, 0, 0)).
JobResult DiagramResult(const std::vector<PersistencePair>& pairs, bool domain = false) {
  const int64_t n = int64_t(pairs.size()), lines = n + (domain || n == 0 ? 0 : 1);
  std::vector<double> points, persistence, birth;
  std::vector<int64_t> offsets;
  std::vector<int32_t> vertex, critical_type, identifier, type;
  std::vector<int8_t> finite;
  for (int64_t i = 0; i < n; ++i) {
    const PersistencePair& p = pairs[size_t(i)];
    if (domain) {
      points.insert(points.end(), {double(p.birth_vertex), 0, 0, double(p.death_vertex), 0, 0});
    } else {
      points.insert(points.end(), {p.birth, p.birth, 0, p.birth, p.death, 0});
    }
    offsets.push_back(2 * i);
    vertex.insert(vertex.end(), {int32_t(p.birth_vertex), int32_t(p.death_vertex)});
    critical_type.insert(critical_type.end(), {p.type, p.finite && p.type < 2 ? p.type + 1 : 3});
    identifier.push_back(int32_t(i));
    type.push_back(p.type);
    persistence.push_back(p.persistence);
    birth.push_back(p.birth);
    finite.push_back(p.finite);
  }
  if (lines > n) {
    // Its two point ids (0 and the last pair's birth) are in no array: the entry counts them.
    offsets.insert(offsets.end(), {2 * n, 2 * n + 2});
    identifier.push_back(-1);
    type.push_back(-1);
    persistence.push_back(2 * persistence[0]);
    birth.push_back(0);
    finite.push_back(0);
  } else if (n > 0) {
    offsets.push_back(2 * n);
  }
  JobResult result;
  const auto add = [&](Array array) { result.arrays[array.name] = std::move(array); };
  add(MakeArray<double>("diagram/Points", points, {2 * n, 3}));
  if (!offsets.empty()) add(MakeArray<int64_t>("diagram/Offsets", offsets, {lines + 1}));
  add(MakeArray<int32_t>("diagram/ttkVertexScalarField", vertex, {2 * n}));
  add(MakeArray<int32_t>("diagram/CriticalType", critical_type, {2 * n}));
  add(MakeArray<float>("diagram/Coordinates", std::vector<float>(6 * size_t(n)), {2 * n, 3}));
  add(MakeArray<int32_t>("diagram/PairIdentifier", identifier, {lines}));
  add(MakeArray<int32_t>("diagram/PairType", type, {lines}));
  add(MakeArray<double>("diagram/Persistence", persistence, {lines}));
  add(MakeArray<double>("diagram/Birth", birth, {lines}));
  add(MakeArray<int8_t>("diagram/IsFinite", finite, {lines}));
  return result;
}

PersistencePair Pair(int type, int64_t birth_vertex, int64_t death_vertex, bool finite,
                     double birth, double death) {
  return {.type = type,
          .birth_vertex = birth_vertex,
          .death_vertex = death_vertex,
          .birth = birth,
          .death = death,
          .persistence = death - birth,
          .finite = finite};
}

// An infinite pair (the global minimum's), then one pair of each type. 0.2 + (0.9 - 0.2) is not
// 0.9 in double, so a death rebuilt as birth + persistence differs from the streamed one.
const std::vector<PersistencePair> kPairs = {
    Pair(0, 10, 40, false, 0.0, 9.0), Pair(0, 9, 12, true, 0.2, 0.9),
    Pair(1, 12, 30, true, 0.9, 6.0), Pair(2, 30, 40, true, 6.0, 9.0)};

std::string Describe(const std::vector<PersistencePair>& pairs) {
  std::string text;
  for (const PersistencePair& p : pairs) {
    text += absl::StrCat(p.type, " ", p.birth_vertex, " ", p.death_vertex, " ", int(p.finite), " ",
                         p.birth, " ", p.death, " ", p.persistence, "\n");
  }
  return text;
}

void ExpectSamePairs(const std::vector<PersistencePair>& got,
                     const std::vector<PersistencePair>& want) {
  ASSERT_EQ(got.size(), want.size()) << Describe(got);
  for (size_t i = 0; i < got.size(); ++i) {
    EXPECT_EQ(got[i].type, want[i].type) << i;
    EXPECT_EQ(got[i].birth_vertex, want[i].birth_vertex) << i;
    EXPECT_EQ(got[i].death_vertex, want[i].death_vertex) << i;
    EXPECT_EQ(got[i].finite, want[i].finite) << i;
    EXPECT_EQ(got[i].birth, want[i].birth) << i;
    EXPECT_EQ(got[i].death, want[i].death) << i;
    EXPECT_EQ(got[i].persistence, want[i].persistence) << i;
  }
}

TEST(PersistencePairsTest, ThePairsWithoutTheDiagonal) {
  const JobResult result = DiagramResult(kPairs);
  ASSERT_EQ(result.Find("diagram/PairIdentifier")->size(), 5);  // the diagonal's line is there
  absl::StatusOr<std::vector<PersistencePair>> pairs = result.PersistencePairs();
  ASSERT_TRUE(pairs.ok()) << pairs.status();
  ExpectSamePairs(*pairs, kPairs);
  EXPECT_FALSE((*pairs)[0].finite);
  EXPECT_TRUE((*pairs)[1].finite);
  EXPECT_EQ((*pairs)[1].death, 0.9);  // from the death point, not 0.2 + (0.9 - 0.2)
}

TEST(PersistencePairsTest, EmbeddedInTheDomainTheDeathIsBirthPlusPersistence) {
  const JobResult result = DiagramResult(kPairs, /*domain=*/true);
  ASSERT_EQ(result.Find("diagram/PairIdentifier")->size(), 4);  // no diagonal
  absl::StatusOr<std::vector<PersistencePair>> pairs = result.PersistencePairs();
  ASSERT_TRUE(pairs.ok()) << pairs.status();
  std::vector<PersistencePair> want = kPairs;
  for (PersistencePair& p : want) p.death = p.birth + p.persistence;
  ExpectSamePairs(*pairs, want);
  EXPECT_NE((*pairs)[1].death, 0.9);  // one bit off the field's value
  EXPECT_DOUBLE_EQ((*pairs)[1].death, 0.9);
}

TEST(PersistencePairsTest, AnEmptyDiagramHasNoPairs) {
  const JobResult result = DiagramResult({});
  EXPECT_EQ(result.Find("diagram/Offsets"), nullptr);  // as the server leaves it out
  absl::StatusOr<std::vector<PersistencePair>> pairs = result.PersistencePairs();
  ASSERT_TRUE(pairs.ok()) << pairs.status();
  EXPECT_TRUE(pairs->empty());
}

// Ids are read by value, whatever their integer width.
TEST(PersistencePairsTest, WiderIdsAreRead) {
  JobResult result = DiagramResult(kPairs);
  const int64_t far = int64_t{1} << 40;
  result.arrays["diagram/ttkVertexScalarField"] = MakeArray<int64_t>(
      "diagram/ttkVertexScalarField", {far, 40, 9, 12, 12, 30, 30, far + 1}, {8});
  absl::StatusOr<std::vector<PersistencePair>> pairs = result.PersistencePairs();
  ASSERT_TRUE(pairs.ok()) << pairs.status();
  EXPECT_EQ((*pairs)[0].birth_vertex, far);
  EXPECT_EQ((*pairs)[3].death_vertex, far + 1);
}

TEST(PersistencePairsTest, MissingArraysAreNamed) {
  absl::StatusOr<std::vector<PersistencePair>> none = JobResult().PersistencePairs();
  EXPECT_EQ(none.status().code(), absl::StatusCode::kNotFound);
  EXPECT_NE(none.status().message().find("'diagram/PairIdentifier' not found"), std::string::npos)
      << none.status();
  EXPECT_NE(none.status().message().find("include_arrays"), std::string::npos) << none.status();
  for (const char* name : {"diagram/Offsets", "diagram/Birth", "diagram/Points"}) {
    JobResult result = DiagramResult(kPairs);
    result.arrays.erase(name);
    absl::StatusOr<std::vector<PersistencePair>> pairs = result.PersistencePairs();
    EXPECT_EQ(pairs.status().code(), absl::StatusCode::kNotFound) << name;
    EXPECT_NE(pairs.status().message().find(absl::StrCat("'", name, "' not found")),
              std::string::npos)
        << pairs.status();
  }
}

// Each way the arrays can miss TTK's layout, and the message that names the array.
TEST(PersistencePairsTest, MalformedArraysAreNamed) {
  Array ragged = MakeArray<int8_t>("diagram/IsFinite", {0, 1, 1, 1, 0}, {5});
  ragged.data.pop_back();
  const struct {
    Array array;  // in place of its namesake among kPairs' arrays
    std::string message;
  } cases[] = {
      {MakeArray<double>("diagram/Birth", {0, 1, 2, 3}, {4}),
       "result array 'diagram/Birth': 4 values, expected 5 (one per line)"},
      {MakeArray<int64_t>("diagram/Offsets", {0, 3, 4, 6, 8, 10}, {6}),
       "result array 'diagram/Offsets': entry 1 is 3, not 2: the pairs' lines are not two points "
       "each"},
      {MakeArray<int64_t>("diagram/Offsets", {0, 2, 4, 6, 8}, {5}),
       "result array 'diagram/Offsets': 5 values, expected 6 (one more than the lines)"},
      {MakeArray<int32_t>("diagram/ttkVertexScalarField", {10, 40, 9}, {3}),
       "result array 'diagram/ttkVertexScalarField': 3 values, expected 8 (two points per pair)"},
      {MakeArray<double>("diagram/Points", std::vector<double>(21), {7, 3}),
       "result array 'diagram/Points': 21 values, expected 24 (x, y, z of two points per pair)"},
      {MakeArray<int32_t>("diagram/PairType", {0, 0, 5, 2, -1}, {5}),
       "result array 'diagram/PairType': line 2 of 5 has type 5; a pair's is 0, 1 or 2"},
      {MakeArray<double>("diagram/PairType", {0, 0, 1, 2, -1}, {5}),
       "array 'diagram/PairType': dtype float64 is not an integer type"},
      {MakeArray<int32_t>("diagram/Persistence", {9, 1, 3, 3, 18}, {5}),
       "result array 'diagram/Persistence': dtype int32 is not a floating-point type"},
      {ragged, "array 'diagram/IsFinite': 4 bytes do not hold 5 int8 values"},
  };
  for (const auto& [array, message] : cases) {
    JobResult result = DiagramResult(kPairs);
    result.arrays[array.name] = array;
    const absl::Status status = result.PersistencePairs().status();
    EXPECT_EQ(status.code(), absl::StatusCode::kInvalidArgument) << status;
    EXPECT_EQ(status.message(), message);
  }
}

ScalarTree::Node TreeNode(int64_t id, int64_t vertex, double scalar, int type) {
  return {.id = id,
          .vertex = vertex,
          .scalar = scalar,
          .critical_type = type,
          .region_size = 10 * id,
          .region_span = double(id)};
}

// Two components of a join tree: a minimum pair merging below a maximum (nodes 0 to 3, vertices
// 10 to 13), and a chain (nodes 4 to 6, vertices 20 to 22); 30 vertices, each a node's on one
// of its arcs, the others on arc 0.
ScalarTree TwoComponents() {
  ScalarTree t;
  t.nodes = {TreeNode(0, 10, 0.0, 0), TreeNode(1, 11, 1.0, 0), TreeNode(2, 12, 2.0, 1),
             TreeNode(3, 13, 3.0, 3), TreeNode(4, 20, 0.5, 0), TreeNode(5, 21, 1.5, 4),
             TreeNode(6, 22, 2.5, 3)};
  t.arcs = {{.down_node = 0, .up_node = 2, .segmentation_id = 0, .region_size = 3},
            {.down_node = 1, .up_node = 2, .segmentation_id = 1, .region_size = 4},
            {.down_node = 2, .up_node = 3, .segmentation_id = 2, .region_size = 5},
            {.down_node = 4, .up_node = 5, .segmentation_id = 4, .region_size = 6, .component = 1},
            {.down_node = 5, .up_node = 6, .segmentation_id = 5, .region_size = 7, .component = 1}};
  for (ScalarTree::Arc& a : t.arcs) a.region_span = 0.25 * double(a.region_size);
  t.component_offsets = {0, 4, 7};
  t.segmentation.assign(30, 0);
  for (const auto& [vertex, id] : std::vector<std::pair<int, int>>{
           {10, 0}, {11, 1}, {12, 2}, {13, 2}, {20, 4}, {21, 5}, {22, 5}}) {
    t.segmentation[size_t(vertex)] = id;
  }
  return t;
}

// The arrays of `t` that Tree() reads, as a merge-tree or contour-tree job streams them:
// up/downNodeId relative to their component's first NodeId, ComponentId per node and per arc.
// (The points and lines, which Tree() does not read, are left out.)
JobResult TreeArrays(const ScalarTree& t) {
  const int64_t n = int64_t(t.nodes.size()), a = int64_t(t.arcs.size());
  std::vector<float> node_scalar;
  std::vector<int32_t> id, vertex, type, size, span, node_component;
  for (const ScalarTree::Node& node : t.nodes) {
    node_scalar.push_back(float(node.scalar));
    id.push_back(int32_t(node.id));
    vertex.push_back(int32_t(node.vertex));
    type.push_back(node.critical_type);
    size.push_back(int32_t(node.region_size));
    span.push_back(int32_t(node.region_span));
    const auto next =
        std::upper_bound(t.component_offsets.begin(), t.component_offsets.end(), node.id);
    node_component.push_back(int32_t(next - t.component_offsets.begin() - 1));
  }
  std::vector<double> arc_span;
  std::vector<int32_t> segmentation_id, up, down, arc_size, arc_component;
  for (const ScalarTree::Arc& arc : t.arcs) {
    const int64_t first = t.component_offsets[size_t(arc.component)];
    segmentation_id.push_back(int32_t(arc.segmentation_id));
    up.push_back(int32_t(arc.up_node - first));
    down.push_back(int32_t(arc.down_node - first));
    arc_size.push_back(int32_t(arc.region_size));
    arc_span.push_back(arc.region_span);
    arc_component.push_back(int32_t(arc.component));
  }

  JobResult result;
  const auto add = [&](Array array) { result.arrays[array.name] = std::move(array); };
  add(MakeArray<int32_t>("tree_nodes/NodeId", id, {n}));
  add(MakeArray<float>("tree_nodes/Scalar", node_scalar, {n}));
  add(MakeArray<int32_t>("tree_nodes/VertexId", vertex, {n}));
  add(MakeArray<int32_t>("tree_nodes/CriticalType", type, {n}));
  add(MakeArray<int32_t>("tree_nodes/RegionSize", size, {n}));
  add(MakeArray<int32_t>("tree_nodes/RegionSpan", span, {n}));
  add(MakeArray<int32_t>("tree_nodes/ComponentId", node_component, {n}));
  add(MakeArray<int32_t>("tree_arcs/SegmentationId", segmentation_id, {a}));
  add(MakeArray<int32_t>("tree_arcs/upNodeId", up, {a}));
  add(MakeArray<int32_t>("tree_arcs/downNodeId", down, {a}));
  add(MakeArray<int32_t>("tree_arcs/RegionSize", arc_size, {a}));
  add(MakeArray<double>("tree_arcs/RegionSpan", arc_span, {a}));
  add(MakeArray<int32_t>("tree_arcs/ComponentId", arc_component, {a}));
  const std::vector<int32_t> segmentation(t.segmentation.begin(), t.segmentation.end());
  add(MakeArray<int32_t>("segmentation/SegmentationId", segmentation,
                         {int64_t(segmentation.size())}));
  return result;
}

void ExpectSameTree(const ScalarTree& got, const ScalarTree& want) {
  ASSERT_EQ(got.nodes.size(), want.nodes.size());
  for (size_t i = 0; i < got.nodes.size(); ++i) {
    const ScalarTree::Node &g = got.nodes[i], &w = want.nodes[i];
    EXPECT_EQ(std::tie(g.id, g.vertex, g.scalar, g.critical_type, g.region_size, g.region_span),
              std::tie(w.id, w.vertex, w.scalar, w.critical_type, w.region_size, w.region_span))
        << "node " << i;
  }
  ASSERT_EQ(got.arcs.size(), want.arcs.size());
  for (size_t i = 0; i < got.arcs.size(); ++i) {
    const ScalarTree::Arc &g = got.arcs[i], &w = want.arcs[i];
    EXPECT_EQ(std::tie(g.down_node, g.up_node, g.segmentation_id, g.region_size, g.region_span,
                       g.component),
              std::tie(w.down_node, w.up_node, w.segmentation_id, w.region_size, w.region_span,
                       w.component))
        << "arc " << i;
  }
  EXPECT_EQ(got.segmentation, want.segmentation);
  EXPECT_EQ(got.component_offsets, want.component_offsets);
}

TEST(TreeTest, GlobalNodeIdsFromTheComponentIds) {
  const ScalarTree want = TwoComponents();
  const JobResult result = TreeArrays(want);
  // The second component's arcs are 0 -> 1 -> 2 on the wire.
  EXPECT_EQ(*result.Get<int32_t>("tree_arcs/downNodeId"), (std::vector<int32_t>{0, 1, 2, 0, 1}));
  absl::StatusOr<ScalarTree> tree = result.Tree();
  ASSERT_TRUE(tree.ok()) << tree.status();
  ExpectSameTree(*tree, want);
}

// Each arc takes its own ComponentId's first NodeId, whatever the arcs' order: here the two
// components' arcs interleaved, and neither component's first arc naming its node 0.
TEST(TreeTest, ArcsInAnyOrder) {
  ScalarTree want = TwoComponents();
  want.arcs = {want.arcs[4], want.arcs[2], want.arcs[3], want.arcs[1], want.arcs[0]};
  const JobResult result = TreeArrays(want);
  EXPECT_EQ(*result.Get<int32_t>("tree_arcs/downNodeId"), (std::vector<int32_t>{1, 2, 0, 1, 0}));
  absl::StatusOr<ScalarTree> tree = result.Tree();
  ASSERT_TRUE(tree.ok()) << tree.status();
  ExpectSameTree(*tree, want);
}

TEST(TreeTest, ANodeAlone) {
  ScalarTree want;
  want.nodes = {TreeNode(0, 0, 1.0, 5)};
  want.component_offsets = {0, 1};
  want.segmentation = {0};
  absl::StatusOr<ScalarTree> tree = TreeArrays(want).Tree();
  ASSERT_TRUE(tree.ok()) << tree.status();
  ExpectSameTree(*tree, want);
  // A vertex in no tetrahedron, on a mesh of other components: a component of its own, its node
  // and an arc from it to itself, as the server writes it.
  want = TwoComponents();
  want.nodes.push_back(TreeNode(7, 29, 9.0, 5));
  want.arcs.push_back({.down_node = 7, .up_node = 7, .segmentation_id = 7, .component = 2});
  want.component_offsets = {0, 4, 7, 8};
  want.segmentation[29] = 7;
  tree = TreeArrays(want).Tree();
  ASSERT_TRUE(tree.ok()) << tree.status();
  ExpectSameTree(*tree, want);
}

TEST(TreeTest, MissingArraysAreNamed) {
  absl::StatusOr<ScalarTree> none = JobResult().Tree();
  EXPECT_EQ(none.status().code(), absl::StatusCode::kNotFound);
  EXPECT_NE(none.status().message().find("'tree_nodes/NodeId' not found"), std::string::npos)
      << none.status();
  EXPECT_NE(none.status().message().find("include_arrays"), std::string::npos) << none.status();
  for (const char* name : {"tree_nodes/Scalar", "tree_nodes/CriticalType", "tree_nodes/ComponentId",
                           "tree_arcs/upNodeId", "tree_arcs/downNodeId", "tree_arcs/ComponentId",
                           "segmentation/SegmentationId"}) {
    JobResult result = TreeArrays(TwoComponents());
    result.arrays.erase(name);
    const absl::Status status = result.Tree().status();
    EXPECT_EQ(status.code(), absl::StatusCode::kNotFound) << name;
    EXPECT_NE(status.message().find(absl::StrCat("'", name, "' not found")), std::string::npos)
        << status;
  }
  // An older server streams no ComponentId: the message says so.
  JobResult result = TreeArrays(TwoComponents());
  result.arrays.erase("tree_arcs/ComponentId");
  EXPECT_EQ(result.Tree().status().message(),
            "result array 'tree_arcs/ComponentId' not found: the server streams it beside TTK's "
            "arrays (a server older than this client does not)");
}

// Each way the arrays can miss the layout, and the message that names the array.
TEST(TreeTest, MalformedArraysAreNamed) {
  const struct {
    Array array;  // in place of its namesake among TwoComponents' arrays
    std::string message;
  } cases[] = {
      {MakeArray<int32_t>("tree_nodes/NodeId", {0, 1, 2, 4, 4, 5, 6}, {7}),
       "result array 'tree_nodes/NodeId': entry 3 is 4, not 3: the nodes are not by NodeId"},
      {MakeArray<float>("tree_nodes/Scalar", {0, 1, 2}, {3}),
       "result array 'tree_nodes/Scalar': 3 values, expected 7 (one per node)"},
      {MakeArray<double>("tree_nodes/VertexId", {10, 11, 12, 13, 20, 21, 22}, {7}),
       "array 'tree_nodes/VertexId': dtype float64 is not an integer type"},
      {MakeArray<int32_t>("tree_nodes/CriticalType", {0, 0, 1, 3, 0, 6, 3}, {7}),
       "result array 'tree_nodes/CriticalType': node 5 has type 6; a node's is 0 to 5"},
      {MakeArray<int32_t>("tree_nodes/ComponentId", {0, 0, 0, 0, 1, 1}, {6}),
       "result array 'tree_nodes/ComponentId': 6 values, expected 7 (one per node)"},
      {MakeArray<float>("tree_nodes/ComponentId", {0, 0, 0, 0, 1, 1, 1}, {7}),
       "array 'tree_nodes/ComponentId': dtype float32 is not an integer type"},
      {MakeArray<int32_t>("tree_nodes/ComponentId", {1, 1, 1, 1, 2, 2, 2}, {7}),
       "result array 'tree_nodes/ComponentId': node 0 is in component 1, not 0: not 0, 1, 2, ... "
       "over NodeId, each component a run"},
      {MakeArray<int32_t>("tree_nodes/ComponentId", {0, 0, 0, 0, 2, 2, 2}, {7}),
       "result array 'tree_nodes/ComponentId': node 4 is in component 2 after 0: not 0, 1, 2, ... "
       "over NodeId, each component a run"},
      {MakeArray<int32_t>("tree_nodes/ComponentId", {0, 0, 1, 1, 0, 1, 1}, {7}),
       "result array 'tree_nodes/ComponentId': node 4 is in component 0 after 1: not 0, 1, 2, ... "
       "over NodeId, each component a run"},
      {MakeArray<int32_t>("tree_arcs/downNodeId", {0, 1, 2, 0}, {4}),
       "result array 'tree_arcs/downNodeId': 4 values, expected 5 (one per arc)"},
      {MakeArray<int32_t>("tree_arcs/ComponentId", {0, 0, 0, 1, 1, 1}, {6}),
       "result array 'tree_arcs/ComponentId': 6 values, expected 5 (one per arc)"},
      {MakeArray<int32_t>("tree_arcs/ComponentId", {0, 0, 0, 1, 2}, {5}),
       "result array 'tree_arcs/ComponentId': arc 4 is in component 2, but "
       "tree_nodes/ComponentId has 2"},
      {MakeArray<int32_t>("tree_arcs/downNodeId", {0, 1, 2, -1, 1}, {5}),
       "result array 'tree_arcs/downNodeId': arc 3 has -1, not within the 3 nodes of its "
       "component (1)"},
      {MakeArray<int32_t>("tree_arcs/upNodeId", {2, 2, 3, 1, 3}, {5}),
       "result array 'tree_arcs/upNodeId': arc 4 has 3, not within the 3 nodes of its component "
       "(1)"},
  };
  for (const auto& [array, message] : cases) {
    JobResult result = TreeArrays(TwoComponents());
    result.arrays[array.name] = array;
    const absl::Status status = result.Tree().status();
    EXPECT_EQ(status.code(), absl::StatusCode::kInvalidArgument) << status;
    EXPECT_EQ(status.message(), message);
  }
}

// A FieldResult reads its arrays as a JobResult does.
TEST(JobResultTest, FieldResultsHaveTheirArrays) {
  JobResult result;
  FieldResult field;
  field.field = "height";
  field.arrays["critical_points/CriticalType"] =
      MakeArray<int8_t>("critical_points/CriticalType", {0, 3}, {2});
  result.fields.push_back(field);
  ASSERT_NE(result.Field("height"), nullptr);
  EXPECT_EQ(result.Field("scalar"), nullptr);
  EXPECT_EQ(*result.Field("height")->Get<int8_t>("critical_points/CriticalType"),
            (std::vector<int8_t>{0, 3}));
  EXPECT_EQ(result.Field("height")->PersistencePairs().status().code(),
            absl::StatusCode::kNotFound);
  EXPECT_EQ(result.Field("height")->Tree().status().code(), absl::StatusCode::kNotFound);
}

// JSON has no infinity: an infinite distance (essential pairs of different counts) is
// "Infinity" as protobuf writes summary_json, null as actopo-bench writes it.
TEST(SeriesTest, DistanceMatrixFromTheSummary) {
  JobResult result;
  result.algorithm = "diagram-distance";
  result.summary_json = R"({"fields": ["a", "b"], "p": 2, "essential": true,
      "wasserstein": [[0, "Infinity"], [null, 0]], "bottleneck": [[0, 1.5], [1.5, 0]],
      "pairs": [3, 4], "thresholds": [0, 0.25], "distance_seconds": 0.01})";
  absl::StatusOr<DistanceMatrix> matrix = result.Distances();
  ASSERT_TRUE(matrix.ok()) << matrix.status();
  EXPECT_EQ(matrix->fields, (std::vector<std::string>{"a", "b"}));
  EXPECT_EQ(matrix->size(), 2u);
  EXPECT_EQ(matrix->p, 2.0);
  EXPECT_TRUE(matrix->essential);
  EXPECT_EQ(matrix->wasserstein[0], 0.0);
  EXPECT_TRUE(std::isinf(matrix->Wasserstein(0, 1)));
  EXPECT_TRUE(std::isinf(matrix->Wasserstein(1, 0)));
  EXPECT_EQ(matrix->bottleneck, (std::vector<double>{0, 1.5, 1.5, 0}));
  EXPECT_EQ(matrix->Bottleneck(1, 0), 1.5);
  EXPECT_EQ(matrix->pairs, (std::vector<int64_t>{3, 4}));
  EXPECT_EQ(matrix->thresholds, (std::vector<double>{0, 0.25}));
  EXPECT_EQ(matrix->distance_seconds, 0.01);

  JobResult ragged = result;
  ragged.summary_json = R"({"fields": ["a", "b"], "p": 2, "essential": false,
      "wasserstein": [[0, 1], [1]], "bottleneck": [[0, 1], [1, 0]],
      "pairs": [3, 4], "thresholds": [0, 0], "distance_seconds": 0})";
  EXPECT_EQ(ragged.Distances().status().code(), absl::StatusCode::kDataLoss);
  EXPECT_NE(ragged.Distances().status().message().find("'wasserstein'"), std::string::npos)
      << ragged.Distances().status();
  ragged.summary_json = R"({"fields": ["a"]})";
  EXPECT_NE(ragged.Distances().status().message().find("'p': missing"), std::string::npos)
      << ragged.Distances().status();
  result.algorithm = "tracking";
  EXPECT_EQ(result.Distances().status().code(), absl::StatusCode::kNotFound);
}

TEST(SeriesTest, TrackingSummary) {
  JobResult result;
  result.algorithm = "tracking";
  result.summary_json = R"({"fields": ["t0", "t1", "t2"], "p": 1, "trajectories": 5,
      "trajectories_by_type": [2, 2, 1], "links": 7, "longest": 3,
      "step_wasserstein": [0.5, 0.75], "step_wasserstein_by_type": [[0.1, 0.2, 0.3], [0, 0, 0.75]],
      "tracking_seconds": 0.002})";
  absl::StatusOr<TrackingSummary> tracking = result.Tracking();
  ASSERT_TRUE(tracking.ok()) << tracking.status();
  EXPECT_EQ(tracking->fields, (std::vector<std::string>{"t0", "t1", "t2"}));
  EXPECT_EQ(tracking->p, 1.0);
  EXPECT_EQ(tracking->trajectories, 5);
  EXPECT_EQ(tracking->trajectories_by_type, (std::vector<int64_t>{2, 2, 1}));
  EXPECT_EQ(tracking->links, 7);
  EXPECT_EQ(tracking->longest, 3);
  EXPECT_EQ(tracking->step_wasserstein, (std::vector<double>{0.5, 0.75}));
  EXPECT_EQ(tracking->step_wasserstein_by_type,
            (std::vector<std::vector<double>>{{0.1, 0.2, 0.3}, {0, 0, 0.75}}));
  EXPECT_EQ(tracking->tracking_seconds, 0.002);

  result.summary_json = R"({"fields": ["t0", "t1"], "p": 1, "trajectories": 2.5})";
  EXPECT_EQ(result.Tracking().status().code(), absl::StatusCode::kDataLoss);
  EXPECT_NE(result.Tracking().status().message().find("'trajectories': not an integer"),
            std::string::npos)
      << result.Tracking().status();
  result.algorithm = "critical-points";
  EXPECT_EQ(result.Tracking().status().code(), absl::StatusCode::kNotFound);
}

TEST(RelationCsrTest, RowsAreSpans) {
  const RelationCsr csr{.offsets = {0, 2, 2, 5}, .values = {1, 2, 3, 4, 5}};
  ASSERT_EQ(csr.size(), 3u);
  EXPECT_EQ(std::vector<int64_t>(csr[0].begin(), csr[0].end()), (std::vector<int64_t>{1, 2}));
  EXPECT_TRUE(csr[1].empty());
  EXPECT_EQ(csr[2].back(), 5);
  EXPECT_EQ(RelationCsr{}.size(), 0u);
}

TEST(SimplexTest, ByIdOrByVertices) {
  const Simplex by_id = 7;
  EXPECT_FALSE(by_id.by_vertices());
  EXPECT_EQ(by_id.id(), 7);
  const Simplex edge = Simplex::Vertices({17, 3});
  EXPECT_TRUE(edge.by_vertices());
  EXPECT_EQ(edge.vertices(), (std::vector<int64_t>{17, 3}));
}

// Ratios at zero requests follow the Python client: nothing was asked, so nothing was missed.
TEST(EngineStatsTest, HitRateIsOneWithoutRequests) {
  EXPECT_EQ(EngineStats{}.hit_rate(), 1.0);
  EXPECT_EQ((EngineStats{.requests = 0, .hits = 0, .misses = 0}).hit_rate(), 1.0);
  EXPECT_EQ((EngineStats{.requests = 4, .hits = 1, .misses = 3}).hit_rate(), 0.25);
  EXPECT_EQ((EngineStats{.requests = 4, .hits = 0, .misses = 4}).hit_rate(), 0.0);
  EXPECT_EQ((EngineStats{.requests = 3, .hits = 3}).hit_rate(), 1.0);
}

TEST(CancelTokenTest, CopiesShareTheFlag) {
  CancelToken token;
  const CancelToken copy = token;
  EXPECT_FALSE(copy.cancelled());
  std::thread([token] { token.Cancel(); }).join();
  EXPECT_TRUE(copy.cancelled());
  token.Cancel();  // idempotent
  EXPECT_TRUE(CancelToken().cancelled() == false);
}

TEST(NamesTest, EnumNames) {
  EXPECT_EQ(StructureName(Structure::kActopo), "actopo");
  EXPECT_EQ(StructureName(Structure::kCompact), "compact");
  EXPECT_EQ(PrefetchName(Prefetch::kAdaptive), "adaptive");
  EXPECT_EQ(PrecomputeName(Precompute::kAuto), "auto");
}

TEST(ConnectTest, NeedsATarget) {
  unsetenv("ACTOPO_SERVER");
  auto client = Client::Connect("");
  EXPECT_EQ(client.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_NE(client.status().message().find("ACTOPO_SERVER"), std::string::npos);
  setenv("ACTOPO_SERVER", "127.0.0.1:1", 1);
  client = Client::Connect("");
  ASSERT_TRUE(client.ok()) << client.status();
  EXPECT_EQ((*client)->target(), "127.0.0.1:1");
  unsetenv("ACTOPO_SERVER");
}

TEST(ConnectTest, RejectsInconsistentOptions) {
  EXPECT_EQ(Client::Connect("127.0.0.1:1", {.tls_root_certs = "PEM"}).status().code(),
            absl::StatusCode::kInvalidArgument);
  EXPECT_EQ(Client::Connect("127.0.0.1:1", {.max_message_bytes = 0}).status().code(),
            absl::StatusCode::kInvalidArgument);
}

TEST(ConnectTest, AffinityKeyIsGivenFromTheEnvironmentOrRandom) {
  unsetenv("ACTOPO_AFFINITY_KEY");
  auto given = Client::Connect("127.0.0.1:1", {.affinity_key = "workflow-7"});
  ASSERT_TRUE(given.ok()) << given.status();
  EXPECT_EQ((*given)->affinity_key(), "workflow-7");

  auto first = Client::Connect("127.0.0.1:1"), second = Client::Connect("127.0.0.1:1");
  ASSERT_TRUE(first.ok() && second.ok());
  const std::string& key = (*first)->affinity_key();
  EXPECT_EQ(key.size(), 32u) << key;
  EXPECT_EQ(key.find_first_not_of("0123456789abcdef"), std::string::npos) << key;
  EXPECT_NE(key, (*second)->affinity_key());

  setenv("ACTOPO_AFFINITY_KEY", "from-env", 1);
  auto from_env = Client::Connect("127.0.0.1:1");
  ASSERT_TRUE(from_env.ok());
  EXPECT_EQ((*from_env)->affinity_key(), "from-env");
  EXPECT_EQ((*Client::Connect("127.0.0.1:1", {.affinity_key = "mine"}))->affinity_key(), "mine");

  setenv("ACTOPO_AFFINITY_KEY", "tab\there", 1);
  auto bad_env = Client::Connect("127.0.0.1:1");
  EXPECT_EQ(bad_env.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_NE(bad_env.status().message().find("ACTOPO_AFFINITY_KEY: 'tab\\there'"), std::string::npos)
      << bad_env.status();
  unsetenv("ACTOPO_AFFINITY_KEY");
  auto bad = Client::Connect("127.0.0.1:1", {.affinity_key = "new\nline"});
  EXPECT_EQ(bad.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_NE(bad.status().message().find("options.affinity_key"), std::string::npos) << bad.status();
}

// Port 1 on loopback: nothing listens there.
TEST(ConnectTest, UnreachableServerIsUnavailable) {
  auto waited = Client::Connect("127.0.0.1:1", {.connect_timeout = std::chrono::milliseconds(300)});
  EXPECT_EQ(waited.status().code(), absl::StatusCode::kUnavailable) << waited.status();
  auto lazy = Client::Connect("127.0.0.1:1", {.default_timeout = std::chrono::seconds(5)});
  ASSERT_TRUE(lazy.ok());
  EXPECT_EQ((*lazy)->GetServerInfo().status().code(), absl::StatusCode::kUnavailable);
}

// Bad names and shapes are refused before anything is sent (the server does not exist).
TEST(ArgumentsTest, CheckedOnTheClient) {
  auto client = Client::Connect("127.0.0.1:1");
  ASSERT_TRUE(client.ok());
  Client& c = **client;
  auto relation = c.Relation("session-x", "vertex_stars", 0);
  EXPECT_EQ(relation.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_NE(relation.status().message().find("unknown relation 'vertex_stars'"), std::string::npos)
      << relation.status();
  EXPECT_NE(relation.status().message().find("vertex_star,"), std::string::npos);
  const std::vector<int64_t> tuples = {1, 2, 3};
  EXPECT_EQ(c.RelationBatchByVertices("s", "edge_star", tuples, 2).status().code(),
            absl::StatusCode::kInvalidArgument);
  EXPECT_EQ(c.RelationBatchByVertices("s", "edge_star", tuples, 0).status().code(),
            absl::StatusCode::kInvalidArgument);
  auto job = c.RunJob("session-x", "morse-smales");
  EXPECT_EQ(job.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_NE(job.status().message().find("morse-smale"), std::string::npos);
  // The algorithm names come from the proto the library was built from.
  EXPECT_NE(job.status().message().find("morse-smale, persistence-diagram, "
                                        "topological-simplification, diagram-distance, tracking"),
            std::string::npos)
      << job.status();
  // A known name passes the client's check and reaches for the server, which is not there.
  for (const char* name :
       {"persistence-diagram", "persistence_diagram", "diagram-distance", "Tracking"}) {
    EXPECT_EQ(c.RunJob("session-x", name).status().code(), absl::StatusCode::kUnavailable) << name;
  }
  CancelToken cancelled;
  cancelled.Cancel();
  EXPECT_EQ(c.RunJob("session-x", "MORSE_SMALE", {}, {.cancel = cancelled}).status().code(),
            absl::StatusCode::kCancelled);
  EXPECT_EQ(c.LoadMesh("x.vtu", {.block_size = -1}).status().code(),
            absl::StatusCode::kInvalidArgument);
  const std::vector<double> points = {0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1};
  const std::vector<int32_t> tets = {0, 1, 2, 3};
  const std::vector<double> short_field = {1, 2, 3};
  EXPECT_EQ(c.UploadMesh(std::span(points).first(10), tets).status().code(),
            absl::StatusCode::kInvalidArgument);
  EXPECT_EQ(c.UploadMesh(points, std::span(tets).first(3)).status().code(),
            absl::StatusCode::kInvalidArgument);
  auto field = c.UploadMesh(points, tets, {{"h", short_field}});
  EXPECT_EQ(field.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_NE(field.status().message().find("3 values for 4 vertices"), std::string::npos)
      << field.status();
  const std::vector<double> height = {0, 0, 0, 1};
  auto twice = c.UploadMesh(points, tets, {{"h", height}, {"h", height}});
  EXPECT_EQ(twice.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_NE(twice.status().message().find("appears twice"), std::string::npos);
  // Added fields: names, lengths, digests and times the client can judge.
  const std::vector<float> narrow = {0, 0, 0, 1};
  const auto added = [&](const std::vector<FieldValues>& fields,
                         const AddFieldsOptions& options = {}) {
    return c.AddFields("mesh-x", fields, options).status();
  };
  const auto expect_invalid = [](const absl::Status& s, const std::string& part) {
    EXPECT_EQ(s.code(), absl::StatusCode::kInvalidArgument) << s;
    EXPECT_NE(s.message().find(part), std::string::npos) << s;
  };
  expect_invalid(added({}), "fields: none given");
  expect_invalid(added({{.name = "", .values = height}}), "fields[0].name: empty");
  expect_invalid(added({{.name = "h", .values = height}, {.name = "h", .values = narrow}}),
                 "fields[1].name: 'h' appears twice");
  expect_invalid(added({{.name = "h", .values = height}, {.name = "g", .values = short_field}}),
                 "fields[1] 'g': 3 values but fields[0] 'h' has 4");
  expect_invalid(added({{.name = "h", .values = std::span<const double>()}}),
                 "fields[0] 'h': 0 values");
  expect_invalid(added({{.name = "h", .values = height, .time = std::nan("")}}),
                 "fields[0] 'h': time nan is not finite");
  expect_invalid(added({{.name = "h", .values = height}}, {.chunk_bytes = 0}),
                 "options.chunk_bytes");
  expect_invalid(added({{.name = "h", .values = height}}, {.sha256 = "ABC"}), "options.sha256");
  expect_invalid(added({{.name = "h", .values = height}}, {.sha256 = std::string(64, 'A')}),
                 "options.sha256");
  // Well formed, they reach for the server.
  EXPECT_EQ(added({{.name = "h", .values = height}, {.name = "n", .values = narrow}}).code(),
            absl::StatusCode::kUnavailable);
  EXPECT_EQ(added({{.name = "h", .values = height}}, {.sha256 = std::string(64, 'a')}).code(),
            absl::StatusCode::kUnavailable);
  expect_invalid(
      c.RunJob("session-x", "tracking", {}, {.fields = {"a", "b"}, .all_fields = true}).status(),
      "give fields or all_fields, not both");
  // Empty inputs need no call at all.
  EXPECT_EQ(c.RelationBatch("s", "vertex_star", {})->size(), 0u);
  EXPECT_TRUE(
      c.StreamRelations("s", "vertex_star", std::span<const int64_t>(), [](StreamItem) {}).ok());
}

}  // namespace
}  // namespace actopo::client
