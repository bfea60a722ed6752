// Server info, meshes, sessions, statistics and errors against a real actopo-server.
#include <unistd.h>

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <future>
#include <sstream>
#include <thread>

#include "tests/testing/fixture.h"

namespace actopo::client::testing {
namespace {

using absl::StatusCode;

TEST_F(ServerTest, ServerInfo) {
  absl::StatusOr<ServerInfo> info = client().GetServerInfo();
  ASSERT_OK(info);
  EXPECT_FALSE(info->version.empty());
  EXPECT_EQ(
      info->algorithms,
      (std::vector<std::string>{"topo-relations", "critical-points", "discrete-gradient",
                                "morse-smale", "persistence-diagram", "topological-simplification",
                                "diagram-distance", "tracking", "merge-tree", "contour-tree"}));
  ASSERT_EQ(info->relations.size(), 22u);
  EXPECT_EQ(info->relations.front(), "vertex_neighbors");
  EXPECT_EQ(info->relations.back(), "triangle_neighbors");
  EXPECT_FALSE(info->library_versions.at("grpc").empty());
  EXPECT_FALSE(info->samples.empty());
  EXPECT_EQ(info->limits.max_batch_size, kSharedMaxBatchSize);
  EXPECT_EQ(info->limits.max_message_bytes, int64_t{64} << 20);
  EXPECT_GT(info->limits.memory_budget_bytes, 0);
  EXPECT_EQ(info->limits.max_meshes, 64);  // the shared server's flag
  EXPECT_EQ(info->limits.max_sessions, 64);
  EXPECT_EQ(info->limits.max_engine_threads, 64);
  EXPECT_EQ(info->limits.session_idle_timeout_seconds, 1800);
  // Every relation the server lists is a name the client accepts.
  const std::string mesh = LoadSample("jittered:3");
  const std::string session = Open(mesh, {.structure = Structure::kExplicit});
  for (const std::string& relation : info->relations) {
    EXPECT_OK(client().Relation(session, relation, 0)) << relation;
  }
  // And every algorithm; those comparing fields over the sample's two.
  for (const std::string& algorithm : info->algorithms) {
    const bool compares = algorithm == "diagram-distance" || algorithm == "tracking";
    absl::StatusOr<JobResult> job =
        client().RunJob(session, algorithm, {}, {.include_arrays = false, .all_fields = compares});
    ASSERT_OK(job) << algorithm;
    EXPECT_EQ(job->algorithm, algorithm);
  }
}

TEST_F(ServerTest, MeshLifecycle) {
  absl::StatusOr<MeshInfo> file = client().LoadMesh("fertility_tet.vtu", {.block_size = 500});
  ASSERT_OK(file);
  meshes_.push_back(file->mesh_id);
  EXPECT_EQ(file->source, "file:fertility_tet.vtu");
  EXPECT_EQ(file->vertices, 14570);
  EXPECT_EQ(file->tetrahedra, 60948);
  // Edges and triangles wait for their first need, or a describe that counts them.
  EXPECT_FALSE(file->edges.has_value());
  absl::StatusOr<MeshInfo> counted = client().GetMesh(file->mesh_id, /*count_faces=*/true);
  ASSERT_OK(counted);
  EXPECT_EQ(counted->edges, 84608);
  EXPECT_EQ(counted->triangles, 130983);
  EXPECT_GT(counted->bytes, file->bytes);
  EXPECT_EQ(file->block_size, 500);
  EXPECT_GT(file->blocks, 14570 / 500);
  std::vector<std::string> fields;
  for (const FieldInfo& f : file->fields) fields.push_back(f.name);
  EXPECT_EQ(fields, (std::vector<std::string>{"eigenfunction4", "height"}));
  EXPECT_NEAR(file->fields[0].min, -0.0191, 1e-4);
  EXPECT_NEAR(file->fields[0].max, 0.0459, 1e-4);
  EXPECT_GT(file->bytes, 0);
  EXPECT_GT(file->created.time_since_epoch().count(), 0);

  absl::StatusOr<MeshInfo> sample = client().LoadMesh("sample:jittered:5");
  ASSERT_OK(sample);
  meshes_.push_back(sample->mesh_id);
  EXPECT_EQ(sample->source, "sample:jittered:5");
  EXPECT_EQ(sample->vertices, 125);
  EXPECT_EQ(sample->tetrahedra, 6 * 64);

  absl::StatusOr<std::vector<MeshInfo>> list = client().ListMeshes();
  ASSERT_OK(list);
  int found = 0;
  for (const MeshInfo& m : *list)
    found += m.mesh_id == file->mesh_id || m.mesh_id == sample->mesh_id;
  EXPECT_EQ(found, 2);

  absl::StatusOr<MeshInfo> described = client().GetMesh(sample->mesh_id);
  ASSERT_OK(described);
  EXPECT_EQ(described->vertices, 125);
  EXPECT_EQ(described->name, sample->name);

  ASSERT_OK(client().DeleteMesh(sample->mesh_id));
  EXPECT_TRUE(HasError(client().GetMesh(sample->mesh_id), StatusCode::kNotFound, sample->mesh_id));
  EXPECT_TRUE(HasError(client().DeleteMesh(sample->mesh_id), StatusCode::kNotFound));
}

TEST_F(ServerTest, LoadWithProgressReportsEachPhaseThenGivesTheMesh) {
  std::vector<std::string> phases;
  double last = 0;
  LoadOptions options;
  options.partition.block_size = 500;
  options.progress = [&](const LoadProgress& p) {
    if (phases.empty() || phases.back() != p.phase) {
      phases.push_back(p.phase);
      last = 0;
    }
    EXPECT_GE(p.fraction, last);
    EXPECT_LE(p.fraction, 1.0);
    last = p.fraction;
  };
  absl::StatusOr<MeshInfo> mesh = client().LoadMeshWithProgress("fertility_tet.vtu", options);
  ASSERT_OK(mesh);
  meshes_.push_back(mesh->mesh_id);
  EXPECT_EQ(phases, (std::vector<std::string>{"read", "partition", "encode"}));
  EXPECT_EQ(mesh->tetrahedra, 60948);
  EXPECT_FALSE(mesh->triangles.has_value());
  EXPECT_EQ(mesh->block_size, 500);
}

TEST_F(ServerTest, CancellingALoadLeavesNoMesh) {
  constexpr char kBig[] = "sample:jittered:80";  // about 3M tetrahedra
  // By the token, once encoding started.
  LoadOptions by_token;
  by_token.progress = [&](const LoadProgress& p) {
    if (p.phase == "encode") by_token.cancel.Cancel();
  };
  absl::StatusOr<MeshInfo> stopped = client().LoadMeshWithProgress(kBig, by_token);
  EXPECT_EQ(stopped.status().code(), StatusCode::kCancelled) << stopped.status();
  // By a callback that throws.
  LoadOptions throwing;
  throwing.progress = [](const LoadProgress& p) {
    if (p.phase == "partition") throw 7;
  };
  EXPECT_THROW(client().LoadMeshWithProgress(kBig, throwing).IgnoreError(), int);
  // The server goes on serving and holds neither load.
  EXPECT_FALSE(LoadSample("jittered:3").empty());
  absl::StatusOr<std::vector<MeshInfo>> list = client().ListMeshes();
  ASSERT_OK(list);
  for (const MeshInfo& m : *list) EXPECT_NE(m.source, kBig);
}

TEST_F(ServerTest, SessionLifecycleAndStats) {
  const std::string mesh = LoadSample("jittered:6");
  for (Structure structure : {Structure::kExplicit, Structure::kCompact, Structure::kActopo}) {
    absl::StatusOr<SessionInfo> opened =
        client().OpenSession(mesh, {.structure = structure,
                                    .buffer_ratio = 0.5,
                                    .prefetch = Prefetch::kSpatial,
                                    .precompute = Precompute::kDeclared});
    ASSERT_OK(opened);
    const std::string id = opened->session_id;
    EXPECT_EQ(id.rfind("session-", 0), 0u);
    EXPECT_EQ(opened->mesh_id, mesh);
    EXPECT_EQ(opened->scalar_field, "scalar");  // the sample's first floating-point field
    EXPECT_EQ(opened->structure, structure) << StructureName(structure);
    EXPECT_EQ(opened->buffer_ratio, 0.5);
    if (structure == Structure::kActopo) {
      EXPECT_EQ(opened->prefetch, Prefetch::kSpatial);
      EXPECT_EQ(opened->precompute, Precompute::kDeclared);
    }

    absl::StatusOr<SessionInfo> described = client().GetSession(id);
    ASSERT_OK(described);
    EXPECT_TRUE(described->running_job_id.empty());
    EXPECT_GE(described->last_used, described->created);
    absl::StatusOr<std::vector<SessionInfo>> list = client().ListSessions();
    ASSERT_OK(list);
    EXPECT_TRUE(std::any_of(list->begin(), list->end(),
                            [&](const SessionInfo& s) { return s.session_id == id; }));

    ASSERT_OK(client().Relation(id, "vertex_star", 7));
    ASSERT_OK(client().Relation(id, "edge_triangles", 3));
    absl::StatusOr<SessionStats> stats = client().Stats(id);
    ASSERT_OK(stats);
    EXPECT_EQ(stats->relation_queries.count, 2);
    EXPECT_GT(stats->relation_queries.ns, 0);
    EXPECT_EQ(stats->jobs.count, 0);
    EXPECT_GT(stats->memory.static_bytes, 0);
    EXPECT_GT(stats->memory.process_rss_bytes, 0);
    EXPECT_GE(stats->engine.requests, stats->engine.hits);

    ASSERT_OK(client().CloseSession(id));
    EXPECT_TRUE(HasError(client().GetSession(id), StatusCode::kNotFound, id));
    EXPECT_TRUE(HasError(client().CloseSession(id), StatusCode::kNotFound));
    EXPECT_TRUE(HasError(client().Stats(id), StatusCode::kNotFound));
  }
  absl::StatusOr<MeshInfo> info = client().GetMesh(mesh);
  ASSERT_OK(info);
  EXPECT_EQ(info->sessions, 0);
}

TEST_F(ServerTest, OpenSessionWithAScalarOfAFile) {
  const std::string session =
      Open(Fertility(), {.scalar = "height", .structure = Structure::kCompact});
  absl::StatusOr<SessionInfo> info = client().GetSession(session);
  ASSERT_OK(info);
  EXPECT_EQ(info->scalar_field, "height");
  EXPECT_EQ(info->structure, Structure::kCompact);
}

TEST_F(ServerTest, ServerErrorsKeepTheirCodeAndMessage) {
  EXPECT_TRUE(HasError(client().LoadMesh("nope.vtu"), StatusCode::kNotFound, "nope.vtu"));
  EXPECT_TRUE(HasError(client().LoadMesh("../outside.vtu"), StatusCode::kInvalidArgument,
                       "outside the server's data directory"));
  EXPECT_TRUE(HasError(client().LoadMesh("sample:teapot"), StatusCode::kInvalidArgument,
                       "sample 'teapot'"));
  EXPECT_TRUE(HasError(client().GetMesh("mesh-nope"), StatusCode::kNotFound, "mesh-nope"));
  EXPECT_TRUE(HasError(client().OpenSession("mesh-nope"), StatusCode::kNotFound, "mesh-nope"));
  const std::string mesh = LoadSample("jittered:5");
  EXPECT_TRUE(HasError(client().OpenSession(mesh, {.scalar = "pressure"}), StatusCode::kNotFound,
                       "'pressure' not found"));
  EXPECT_TRUE(HasError(client().OpenSession(mesh, {.producers = 500}), StatusCode::kInvalidArgument,
                       "engine.producers: 500"));
  EXPECT_TRUE(HasError(client().OpenSession(mesh, {.buffer_ratio = -2}),
                       StatusCode::kInvalidArgument, "engine.buffer_ratio: -2"));
  EXPECT_TRUE(
      HasError(client().GetSession("session-guess"), StatusCode::kNotFound, "session-guess"));
  EXPECT_TRUE(HasError(client().CancelJob("job-x"), StatusCode::kNotFound, "job-x"));
}

// A load held by the server outlasts the client's mesh deadline.
TEST_F(ServerTest, DeadlinesApply) {
  auto impatient = Client::Connect(target(), {.default_timeout = std::chrono::seconds(1),
                                              .mesh_timeout = std::chrono::seconds(1)});
  ASSERT_OK(impatient);
  std::unique_ptr<WorkHold> hold = Hold("LoadMesh");
  EXPECT_TRUE(
      HasError((*impatient)->LoadMesh("sample:jittered:20"), StatusCode::kDeadlineExceeded));
  EXPECT_TRUE(hold->WaitHeld(std::chrono::milliseconds(0))) << "the load was not held";
}

// A second server with a token and tight limits.
TEST_F(ServerTest, TokenAndLimits) {
  auto server = ServerProcess::Start(
      ServerBinary(), DataDir(), {"--token", "s3cret", "--max-meshes", "1", "--max-sessions", "1"});
  ASSERT_OK(server);
  auto anonymous = Client::Connect((*server)->target());
  ASSERT_OK(anonymous);
  EXPECT_TRUE(HasError((*anonymous)->GetServerInfo(), StatusCode::kUnauthenticated));
  auto wrong = Client::Connect((*server)->target(), {.token = "guess"});
  ASSERT_OK(wrong);
  EXPECT_TRUE(HasError((*wrong)->ListMeshes(), StatusCode::kUnauthenticated));

  auto client = Client::Connect((*server)->target(), {.token = "s3cret"});
  ASSERT_OK(client);
  Client& c = **client;
  ASSERT_OK(c.GetServerInfo());
  absl::StatusOr<MeshInfo> mesh = c.LoadMesh("sample:jittered:4");
  ASSERT_OK(mesh);
  EXPECT_TRUE(HasError(c.LoadMesh("sample:jittered:3"), StatusCode::kResourceExhausted));
  ASSERT_OK(c.OpenSession(mesh->mesh_id));
  EXPECT_TRUE(HasError(c.OpenSession(mesh->mesh_id), StatusCode::kResourceExhausted,
                       "maximum of 1 session"));
  // Streams carry the token too.
  absl::StatusOr<std::vector<SessionInfo>> sessions = c.ListSessions();
  ASSERT_OK(sessions);
  ASSERT_EQ(sessions->size(), 1u);
  int answered = 0;
  const std::vector<int64_t> ids = {0, 1, 2};
  ASSERT_OK(c.StreamRelations(sessions->front().session_id, "vertex_star", ids,
                              [&](StreamItem item) { answered += item.ids.ok(); }));
  EXPECT_EQ(answered, 3);
  ASSERT_OK(c.RunJob(sessions->front().session_id, "critical-points"));
}

// Reads made while the server restarts on the same port are retried until it is back (the
// server's state is gone: old ids are NOT_FOUND); without retries they fail at once. Calls that
// change state are never retried.
TEST_F(ServerTest, ReadsRideOutARestartAndNothingElseIsRetried) {
  auto first = ServerProcess::Start(ServerBinary(), DataDir());
  ASSERT_OK(first);
  const int port = (*first)->port();
  auto client = Client::Connect((*first)->target());
  ASSERT_OK(client);
  auto once = Client::Connect((*first)->target(), {.retries = false});
  ASSERT_OK(once);
  absl::StatusOr<MeshInfo> mesh = (*client)->LoadMesh("sample:jittered:4");
  ASSERT_OK(mesh);
  ASSERT_OK((*once)->GetServerInfo());

  first->reset();  // SIGTERM; the port is free once this returns
  EXPECT_TRUE(HasError((*once)->GetServerInfo(), StatusCode::kUnavailable));
  EXPECT_TRUE(HasError((*client)->LoadMesh("sample:jittered:4"), StatusCode::kUnavailable));

  // The read runs on another thread: the server must be started from this one, as it dies with
  // the thread that started it (PR_SET_PDEATHSIG). The read is asked before the restart begins
  // and no server listens until then, so under any schedule its success means it was retried
  // until the second server answered.
  absl::StatusOr<ServerInfo> info = absl::UnknownError("not asked");
  std::promise<void> asking;
  std::thread reader([&] {
    asking.set_value();
    info = (*client)->GetServerInfo();
  });
  asking.get_future().wait();
  auto second = ServerProcess::Start(ServerBinary(), DataDir(), {"--port", std::to_string(port)});
  reader.join();
  ASSERT_OK(second);
  EXPECT_OK(info);
  EXPECT_TRUE(HasError((*client)->GetMesh(mesh->mesh_id), StatusCode::kNotFound));
}

// A third server over TLS with a self-signed certificate for 127.0.0.1.
TEST_F(ServerTest, Tls) {
  if (std::system("command -v openssl > /dev/null") != 0) ACTOPO_SKIP() << "no openssl command";
  const std::filesystem::path dir =
      std::filesystem::temp_directory_path() / ("actopo-client-tls-" + std::to_string(getpid()));
  std::filesystem::create_directories(dir);
  const std::string cert = (dir / "cert.pem").string(), key = (dir / "key.pem").string();
  const std::string command =
      "openssl req -x509 -newkey rsa:2048 -nodes -days 1 -subj /CN=127.0.0.1 "
      "-addext subjectAltName=IP:127.0.0.1 -keyout " +
      key + " -out " + cert + " > /dev/null 2>&1";
  ASSERT_EQ(std::system(command.c_str()), 0) << command;
  std::stringstream pem;
  pem << std::ifstream(cert).rdbuf();

  auto server =
      ServerProcess::Start(ServerBinary(), DataDir(), {"--tls-cert", cert, "--tls-key", key});
  ASSERT_OK(server);
  auto client =
      Client::Connect((*server)->target(), {.use_tls = true, .tls_root_certs = pem.str()});
  ASSERT_OK(client);
  EXPECT_OK((*client)->GetServerInfo());
  auto plaintext =
      Client::Connect((*server)->target(), {.default_timeout = std::chrono::seconds(5)});
  ASSERT_OK(plaintext);
  EXPECT_TRUE(HasError((*plaintext)->GetServerInfo(), StatusCode::kUnavailable));
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace actopo::client::testing
