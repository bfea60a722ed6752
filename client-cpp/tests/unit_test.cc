// What the client does without a server: arrays, names, statistics, tokens, argument checks.
#include <gtest/gtest.h>

#include <cstdlib>
#include <cstring>
#include <iostream>
#include <thread>

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
  // Empty inputs need no call at all.
  EXPECT_EQ(c.RelationBatch("s", "vertex_star", {})->size(), 0u);
  EXPECT_TRUE(
      c.StreamRelations("s", "vertex_star", std::span<const int64_t>(), [](StreamItem) {}).ok());
}

}  // namespace
}  // namespace actopo::client
