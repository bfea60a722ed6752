// Every RPC against a real server in the test process.
#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <cstring>
#include <fstream>
#include <map>
#include <numeric>
#include <thread>

#include "google/protobuf/util/json_util.h"
#include "server/algorithms/digest.h"
#include "server/algorithms/vertex_order.h"
#include "server/core/explicit_structure.h"
#include "server/core/partition.h"
#include "server/core/testing/status.h"
#include "server/core/testing/wait.h"
#include "server/results/result_files.h"
#include "server/results/run_algorithm.h"
#include "server/service/testing/service_fixture.h"

namespace actopo::service {
namespace {

using testing::JobRun;
using testing::RunJob;
using testing::ServiceTest;

TEST_F(ServiceTest, ServerInfo) {
  v1::GetServerInfoResponse info;
  ASSERT_TRUE(stub_->GetServerInfo(Context().get(), {}, &info).ok());
  EXPECT_EQ(info.algorithms_size(), 10);
  EXPECT_EQ(info.algorithms(4), "persistence-diagram");
  EXPECT_EQ(info.algorithms(5), "topological-simplification");
  EXPECT_EQ(info.algorithms(6), "diagram-distance");
  EXPECT_EQ(info.algorithms(7), "tracking");
  EXPECT_EQ(info.algorithms(8), "merge-tree");
  EXPECT_EQ(info.algorithms(9), "contour-tree");
  EXPECT_EQ(info.relations_size(), kNumRelations);
  EXPECT_EQ(info.relations(0), "vertex_neighbors");
  EXPECT_FALSE(info.library_versions().at("grpc").empty());
  EXPECT_GT(info.limits().max_batch_size(), 0);
}

TEST_F(ServiceTest, MeshLifecycle) {
  const std::string sample = LoadSample("jittered:5");
  v1::LoadMeshRequest file;
  file.set_path("sub/cube.vtu");
  v1::LoadMeshResponse loaded;
  ASSERT_TRUE(stub_->LoadMesh(Context().get(), file, &loaded).ok());
  EXPECT_EQ(loaded.mesh().vertices(), 216);
  EXPECT_EQ(loaded.mesh().tetrahedra(), 6 * 125);
  EXPECT_EQ(loaded.mesh().source(), "file:sub/cube.vtu");
  v1::ListMeshesResponse list;
  ASSERT_TRUE(stub_->ListMeshes(Context().get(), {}, &list).ok());
  EXPECT_EQ(list.meshes_size(), 2);
  v1::GetMeshRequest get;
  get.set_mesh_id(sample);
  v1::GetMeshResponse described;
  ASSERT_TRUE(stub_->GetMesh(Context().get(), get, &described).ok());
  EXPECT_EQ(described.mesh().vertices(), 125);
  EXPECT_GT(described.mesh().blocks(), 1);
  EXPECT_EQ(described.mesh().fields_size(), 2);
  // Edges and triangles wait for their first need, or a describe that asks for them.
  EXPECT_FALSE(described.mesh().has_edges());
  get.set_count_faces(true);
  ASSERT_TRUE(stub_->GetMesh(Context().get(), get, &described).ok());
  const v1::MeshInfo& m = described.mesh();
  ASSERT_TRUE(m.has_edges() && m.has_triangles());
  EXPECT_EQ(m.vertices() - m.edges() + m.triangles() - m.tetrahedra(), 1);  // a ball
  v1::DeleteMeshRequest del;
  del.set_mesh_id(sample);
  v1::DeleteMeshResponse deleted;
  ASSERT_TRUE(stub_->DeleteMesh(Context().get(), del, &deleted).ok());
  EXPECT_EQ(stub_->GetMesh(Context().get(), get, &described).error_code(),
            grpc::StatusCode::NOT_FOUND);
  EXPECT_EQ(stub_->DeleteMesh(Context().get(), del, &deleted).error_code(),
            grpc::StatusCode::NOT_FOUND);
}

TEST_F(ServiceTest, SessionLifecycleAndStats) {
  const std::string mesh = LoadSample("jittered:6");
  for (v1::Structure structure :
       {v1::STRUCTURE_EXPLICIT, v1::STRUCTURE_COMPACT, v1::STRUCTURE_ACTOPO}) {
    const std::string id = Open(mesh, structure);
    ASSERT_EQ(id.rfind("session-", 0), 0u);
    EXPECT_GE(id.size(), 40u);  // 128 random bits
    v1::GetSessionRequest get;
    get.set_session_id(id);
    v1::GetSessionResponse session;
    ASSERT_TRUE(stub_->GetSession(Context().get(), get, &session).ok());
    EXPECT_EQ(session.session().scalar_field(), "scalar");
    EXPECT_EQ(session.session().structure(), structure);
    v1::GetRelationRequest q;
    q.set_session_id(id);
    q.set_relation(v1::RELATION_VERTEX_STAR);
    q.mutable_simplex()->set_id(7);
    v1::GetRelationResponse r;
    ASSERT_TRUE(stub_->GetRelation(Context().get(), q, &r).ok());
    v1::GetSessionStatsRequest sr;
    sr.set_session_id(id);
    v1::GetSessionStatsResponse stats;
    ASSERT_TRUE(stub_->GetSessionStats(Context().get(), sr, &stats).ok());
    EXPECT_EQ(stats.relation_queries().count(), 1);
    EXPECT_GT(stats.memory().static_bytes(), 0);
    EXPECT_GT(stats.memory().process_rss_bytes(), 0);
    v1::CloseSessionRequest close;
    close.set_session_id(id);
    v1::CloseSessionResponse closed;
    ASSERT_TRUE(stub_->CloseSession(Context().get(), close, &closed).ok());
    EXPECT_EQ(stub_->GetSession(Context().get(), get, &session).error_code(),
              grpc::StatusCode::NOT_FOUND);
  }
  v1::ListSessionsResponse list;
  ASSERT_TRUE(stub_->ListSessions(Context().get(), {}, &list).ok());
  EXPECT_EQ(list.sessions_size(), 0);
}

// Relations through the service equal the core's, translated to input ids.
TEST_F(ServiceTest, RelationsMatchTheCore) {
  const Mesh mesh = OkValue(io::MakeSample("jittered:5"));
  const std::string mesh_id = LoadSample("jittered:5", 50);
  auto topo = OkValue(Topology::Build(mesh, OctreeBlocks(mesh.points, {.bucket_capacity = 50})));
  auto structure = OkValue(ExplicitStructure::Build(topo, {}));
  auto reader = structure->NewReader();
  for (v1::Structure kind : {v1::STRUCTURE_EXPLICIT, v1::STRUCTURE_COMPACT, v1::STRUCTURE_ACTOPO}) {
    const std::string session = Open(mesh_id, kind);
    for (Relation r : AllRelations()) {
      const int dim = SourceDimension(r);
      for (SimplexId s = 0; s < topo->num_simplices(dim); s += 7) {
        v1::GetRelationRequest q;
        q.set_session_id(session);
        q.set_relation(static_cast<v1::Relation>(Index(r) + 1));
        const SimplexId wire = dim == 0   ? topo->vertex_input_id(s)
                               : dim == 3 ? topo->tetrahedron_input_id(s)
                                          : s;
        q.mutable_simplex()->set_id(wire);
        v1::GetRelationResponse answer;
        ASSERT_TRUE(stub_->GetRelation(Context().get(), q, &answer).ok());
        // The core's row in wire ids, ordered by the wire's rules: ascending ids; faces by
        // their input vertices; links by the input ids of the star they come from.
        const int t = TargetDimension(r);
        const auto row = reader.get(r, s);
        std::vector<std::pair<std::vector<int64_t>, int64_t>> keyed;
        for (size_t i = 0; i < row.size(); ++i) {
          const SimplexId x = row[i];
          const int64_t id = t == 0   ? topo->vertex_input_id(x)
                             : t == 3 ? topo->tetrahedron_input_id(x)
                                      : x;
          std::vector<int64_t> key = {id};
          if (r == Relation::kFE || r == Relation::kTE || r == Relation::kTF) {
            const auto v = CellInputVertices(*topo, t, x);
            key.assign(v.begin(), v.end());
          }
          if (r == Relation::kVL) key = {topo->tetrahedron_input_id(reader.vertex_star(s)[i])};
          if (r == Relation::kEL) key = {topo->tetrahedron_input_id(reader.edge_star(s)[i])};
          if (r == Relation::kFL) key = {topo->tetrahedron_input_id(reader.triangle_star(s)[i])};
          if (t < 0) key = {0};
          keyed.push_back({key, id});
        }
        std::stable_sort(keyed.begin(), keyed.end(),
                         [](const auto& a, const auto& b) { return a.first < b.first; });
        std::vector<int64_t> expected;
        for (const auto& k : keyed) expected.push_back(k.second);
        if (t >= 0 && r != Relation::kFE && r != Relation::kTE && r != Relation::kTF &&
            r != Relation::kVL && r != Relation::kEL && r != Relation::kFL) {
          EXPECT_TRUE(std::is_sorted(expected.begin(), expected.end()));
        }
        ASSERT_EQ(std::vector<int64_t>(answer.ids().begin(), answer.ids().end()), expected)
            << RelationName(r) << " of " << wire;
        // The same simplex by its vertices.
        if (dim > 0) {
          q.mutable_simplex()->mutable_vertices()->Clear();
          for (SimplexId v : CellInputVertices(*topo, dim, s)) {
            q.mutable_simplex()->mutable_vertices()->add_ids(v);
          }
          v1::GetRelationResponse by_tuple;
          ASSERT_TRUE(stub_->GetRelation(Context().get(), q, &by_tuple).ok());
          EXPECT_EQ(by_tuple.ids_size(), answer.ids_size());
        }
      }
    }
  }
}

TEST_F(ServiceTest, BatchEqualsSingles) {
  const std::string mesh = LoadSample("jittered:6");
  for (v1::Structure structure : {v1::STRUCTURE_COMPACT, v1::STRUCTURE_ACTOPO}) {
    const std::string session = Open(mesh, structure);
    // Out of block order, with repeats: computing structures answer in block order, then
    // put the rows back in the caller's.
    std::vector<int64_t> ids = {215, 0, 42, 5, 17, 100, 42, 199, 0, 3};
    v1::GetRelationBatchRequest batch;
    batch.set_session_id(session);
    batch.set_relation(v1::RELATION_VERTEX_EDGES);
    batch.mutable_ids()->set_dtype(v1::DATA_TYPE_INT64);
    batch.mutable_ids()->add_shape(int64_t(ids.size()));
    batch.mutable_ids()->set_data(
        std::string(reinterpret_cast<const char*>(ids.data()), ids.size() * sizeof(int64_t)));
    v1::GetRelationBatchResponse response;
    ASSERT_TRUE(stub_->GetRelationBatch(Context().get(), batch, &response).ok());
    std::vector<int64_t> offsets(response.offsets().data().size() / 8);
    std::memcpy(offsets.data(), response.offsets().data().data(), offsets.size() * 8);
    std::vector<int64_t> values(response.values().data().size() / 8);
    std::memcpy(values.data(), response.values().data().data(), values.size() * 8);
    ASSERT_EQ(offsets.size(), ids.size() + 1);
    for (size_t i = 0; i < ids.size(); ++i) {
      v1::GetRelationRequest q;
      q.set_session_id(session);
      q.set_relation(v1::RELATION_VERTEX_EDGES);
      q.mutable_simplex()->set_id(ids[i]);
      v1::GetRelationResponse one;
      ASSERT_TRUE(stub_->GetRelation(Context().get(), q, &one).ok());
      EXPECT_EQ(std::vector<int64_t>(values.begin() + offsets[i], values.begin() + offsets[i + 1]),
                std::vector<int64_t>(one.ids().begin(), one.ids().end()));
    }
  }
}

TEST_F(ServiceTest, AnAnswerOverTheMessageLimitIsRefusedWithAdvice) {
  options_.max_message_bytes = 1 << 20;
  StartServer();
  const std::string session = Open(LoadSample("jittered:30"), v1::STRUCTURE_COMPACT);
  std::vector<int64_t> ids(30 * 30 * 30);
  std::iota(ids.begin(), ids.end(), 0);
  v1::GetRelationBatchRequest batch;
  batch.set_session_id(session);
  batch.set_relation(v1::RELATION_VERTEX_STAR);
  batch.mutable_ids()->set_dtype(v1::DATA_TYPE_INT64);
  batch.mutable_ids()->add_shape(int64_t(ids.size()));
  batch.mutable_ids()->set_data(
      std::string(reinterpret_cast<const char*>(ids.data()), ids.size() * sizeof(int64_t)));
  v1::GetRelationBatchResponse response;
  const grpc::Status s = stub_->GetRelationBatch(Context().get(), batch, &response);
  EXPECT_EQ(s.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED);
  EXPECT_NE(s.error_message().find("message limit of 1 MiB"), std::string::npos)
      << s.error_message();
  EXPECT_NE(s.error_message().find("StreamRelations"), std::string::npos);
}

v1::Array Int64Array(const std::vector<int64_t>& values, std::vector<int64_t> shape = {}) {
  v1::Array a;
  a.set_dtype(v1::DATA_TYPE_INT64);
  if (shape.empty()) shape = {int64_t(values.size())};
  for (int64_t n : shape) a.add_shape(n);
  a.set_data(std::string(reinterpret_cast<const char*>(values.data()), values.size() * 8));
  return a;
}

std::vector<int64_t> Int64s(const v1::Array& a) {
  std::vector<int64_t> v(a.data().size() / 8);
  std::memcpy(v.data(), a.data().data(), v.size() * 8);
  return v;
}

// Rows of a CSR answer.
std::vector<std::vector<int64_t>> Rows(const v1::Array& offsets, const v1::Array& values) {
  const std::vector<int64_t> o = Int64s(offsets), v = Int64s(values);
  std::vector<std::vector<int64_t>> rows;
  for (size_t i = 0; i + 1 < o.size(); ++i)
    rows.emplace_back(v.begin() + o[i], v.begin() + o[i + 1]);
  return rows;
}

std::vector<int64_t> Single(v1::TopologyService::Stub& stub, const std::string& session,
                            v1::Relation relation, int64_t id) {
  v1::GetRelationRequest q;
  q.set_session_id(session);
  q.set_relation(relation);
  q.mutable_simplex()->set_id(id);
  v1::GetRelationResponse one;
  grpc::ClientContext context;
  EXPECT_TRUE(stub.GetRelation(&context, q, &one).ok());
  return {one.ids().begin(), one.ids().end()};
}

// Batches on a stream, written ahead of reading: every row equals the single query's answer
// (which RelationsMatchTheCore checks against the core), bad items fail alone, by position.
TEST_F(ServiceTest, StreamedBatchesEqualSinglesAndKeepItemErrors) {
  const std::string mesh = LoadSample("jittered:6", 40);
  for (v1::Structure kind : {v1::STRUCTURE_EXPLICIT, v1::STRUCTURE_COMPACT, v1::STRUCTURE_ACTOPO}) {
    const std::string session = Open(mesh, kind);
    auto context = Context();
    auto stream = stub_->StreamRelations(context.get());
    constexpr int kMessages = 40;
    std::vector<std::vector<int64_t>> sent;
    for (int m = 0; m < kMessages; ++m) {
      std::vector<int64_t> ids;
      for (int i = 0; i < 50; ++i) ids.push_back((m * 37 + i * 11) % 216);
      if (m % 10 == 3) ids[2] = 216;  // one past the last vertex
      v1::StreamRelationsRequest q;
      q.set_request_id(m);
      q.set_session_id(session);
      q.set_relation(v1::RELATION_VERTEX_STAR);
      *q.mutable_ids() = Int64Array(ids);
      ASSERT_TRUE(stream->Write(q));
      sent.push_back(ids);
    }
    // A batch by vertex tuples (edges), and one failing as a whole.
    v1::StreamRelationsRequest edges;
    edges.set_request_id(kMessages);
    edges.set_session_id(session);
    edges.set_relation(v1::RELATION_EDGE_TRIANGLES);
    *edges.mutable_vertex_tuples() = Int64Array({0, 1, 0, 6, 0, 36}, {3, 2});
    ASSERT_TRUE(stream->Write(edges));
    v1::StreamRelationsRequest bad = edges;
    bad.set_request_id(kMessages + 1);
    bad.set_session_id("session-none");
    ASSERT_TRUE(stream->Write(bad));
    stream->WritesDone();

    for (int m = 0; m < kMessages; ++m) {
      v1::StreamRelationsResponse r;
      ASSERT_TRUE(stream->Read(&r));
      ASSERT_EQ(r.request_id(), m);
      ASSERT_FALSE(r.has_error()) << r.error().message();
      const auto rows = Rows(r.offsets(), r.values());
      ASSERT_EQ(rows.size(), sent[m].size());
      if (m % 10 == 3) {
        ASSERT_EQ(r.item_errors_size(), 1);
        EXPECT_EQ(r.item_errors(0).index(), 2);
        EXPECT_EQ(r.item_errors(0).code(), int(grpc::StatusCode::OUT_OF_RANGE));
        EXPECT_NE(r.item_errors(0).message().find("ids[2]: vertex id 216"), std::string::npos)
            << r.item_errors(0).message();
        EXPECT_TRUE(rows[2].empty());
      } else {
        EXPECT_EQ(r.item_errors_size(), 0);
      }
      for (size_t i = 0; i < rows.size(); i += 7) {
        if (m % 10 == 3 && i == 2) continue;
        EXPECT_EQ(rows[i], Single(*stub_, session, v1::RELATION_VERTEX_STAR, sent[m][i]))
            << "message " << m << " item " << i;
      }
    }
    v1::StreamRelationsResponse r;
    ASSERT_TRUE(stream->Read(&r));
    EXPECT_EQ(r.request_id(), kMessages);
    const auto rows = Rows(r.offsets(), r.values());
    ASSERT_EQ(rows.size(), 3u);
    for (const auto& row : rows) EXPECT_FALSE(row.empty());  // (0,1), (0,6), (0,36) are edges
    ASSERT_TRUE(stream->Read(&r));
    EXPECT_EQ(r.error().code(), int(grpc::StatusCode::NOT_FOUND));
    EXPECT_FALSE(r.has_offsets());
    EXPECT_TRUE(stream->Finish().ok());
  }
}

// Several calls read one session at once (each with a reader of its own) and all get the
// explicit structure's answers; the session accounts every simplex in its query breakdown.
TEST_F(ServiceTest, ConcurrentBatchesOnOneSession) {
  const std::string mesh = LoadSample("jittered:10", 60);
  const std::string reference = Open(mesh, v1::STRUCTURE_EXPLICIT);
  std::vector<int64_t> all(1000);
  std::iota(all.begin(), all.end(), 0);
  const auto batch = [&](const std::string& session, v1::Relation relation) {
    v1::GetRelationBatchRequest request;
    request.set_session_id(session);
    request.set_relation(relation);
    *request.mutable_ids() = Int64Array(all);
    v1::GetRelationBatchResponse response;
    grpc::ClientContext context;
    EXPECT_TRUE(stub_->GetRelationBatch(&context, request, &response).ok());
    return Rows(response.offsets(), response.values());
  };
  const v1::Relation relations[] = {v1::RELATION_VERTEX_STAR, v1::RELATION_VERTEX_TRIANGLES,
                                    v1::RELATION_VERTEX_LINK};
  std::vector<std::vector<std::vector<int64_t>>> expected;
  for (v1::Relation r : relations) expected.push_back(batch(reference, r));
  for (v1::Structure kind : {v1::STRUCTURE_COMPACT, v1::STRUCTURE_ACTOPO}) {
    v1::OpenSessionRequest open;
    open.set_mesh_id(mesh);
    open.set_structure(kind);
    open.mutable_engine()->set_query_readers(3);
    open.mutable_engine()->set_buffer_ratio(0.05);  // misses, evictions: readers really work
    v1::OpenSessionResponse opened;
    ASSERT_TRUE(stub_->OpenSession(Context().get(), open, &opened).ok());
    EXPECT_EQ(opened.session().engine().query_readers(), 3);
    const std::string session = opened.session().session_id();
    constexpr int kThreads = 6, kCalls = 4;
    std::vector<std::thread> threads;
    std::atomic<int> mismatches{0};
    for (int t = 0; t < kThreads; ++t) {
      threads.emplace_back([&, t] {
        for (int c = 0; c < kCalls; ++c) {
          const int k = (t + c) % 3;
          if (batch(session, relations[k]) != expected[k]) ++mismatches;
        }
      });
    }
    for (std::thread& t : threads) t.join();
    EXPECT_EQ(mismatches.load(), 0) << "structure " << int(kind);
    v1::GetSessionStatsRequest get;
    get.set_session_id(session);
    v1::GetSessionStatsResponse stats;
    ASSERT_TRUE(stub_->GetSessionStats(Context().get(), get, &stats).ok());
    EXPECT_EQ(stats.relation_queries().count(), kThreads * kCalls);
    EXPECT_EQ(stats.query_breakdown().simplices(), int64_t(kThreads) * kCalls * 1000);
    EXPECT_GT(stats.query_breakdown().compute_ns(), 0);
    EXPECT_GT(stats.query_breakdown().serialize_ns(), 0);
    EXPECT_GT(stats.engine().misses(), 0);
  }
}

TEST_F(ServiceTest, StreamKeepsGoingAfterBadItems) {
  const std::string session = Open(LoadSample("jittered:5"), v1::STRUCTURE_COMPACT);
  auto context = Context();
  auto stream = stub_->StreamRelations(context.get());
  const std::vector<int64_t> ids = {3, -1, 4, 99999, 5};
  for (size_t i = 0; i < ids.size(); ++i) {
    v1::StreamRelationsRequest q;
    q.set_request_id(int64_t(100 + i));
    q.set_session_id(session);
    q.set_relation(v1::RELATION_VERTEX_NEIGHBORS);
    q.mutable_simplex()->set_id(ids[i]);
    ASSERT_TRUE(stream->Write(q));
    v1::StreamRelationsResponse r;
    ASSERT_TRUE(stream->Read(&r));
    EXPECT_EQ(r.request_id(), int64_t(100 + i));
    if (ids[i] < 0 || ids[i] > 1000) {
      EXPECT_EQ(r.error().code(), int(grpc::StatusCode::OUT_OF_RANGE));
      EXPECT_NE(r.error().message().find(std::to_string(ids[i])), std::string::npos);
    } else {
      EXPECT_FALSE(r.has_error());
      EXPECT_GT(r.ids_size(), 0);
    }
  }
  stream->WritesDone();
  EXPECT_TRUE(stream->Finish().ok());
}

// A client that cancels while the server is still answering, writing and reading: a write
// fails and the server finishes the call; a request read or an answer computed just then is
// dropped, never answered on the finished call. Rounds cancel after 0 to 4 answers read, to meet
// those events in every order; each stream ends CANCELLED and the session keeps serving.
TEST_F(ServiceTest, CancellingWhileAnswersAreWrittenEndsOnlyThatStream) {
  const std::string session = Open(LoadSample("jittered:12", 100), v1::STRUCTURE_COMPACT);
  std::vector<int64_t> vertices(13 * 13 * 13);
  std::iota(vertices.begin(), vertices.end(), 0);
  v1::StreamRelationsRequest request;
  request.set_session_id(session);
  request.set_relation(v1::RELATION_VERTEX_STAR);
  *request.mutable_ids() = Int64Array(vertices);
  for (int round = 0; round < 30; ++round) {
    auto context = Context();
    auto stream = stub_->StreamRelations(context.get());
    std::thread writer([&] {
      v1::StreamRelationsRequest q = request;
      for (int m = 0; m < 200; ++m) {
        q.set_request_id(m);
        if (!stream->Write(q)) return;  // the call ended
      }
      stream->WritesDone();
    });
    v1::StreamRelationsResponse r;
    for (int i = 0; i < round % 5; ++i) {
      ASSERT_TRUE(stream->Read(&r));
      EXPECT_EQ(r.request_id(), i);
    }
    context->TryCancel();
    writer.join();
    while (stream->Read(&r)) {
    }
    EXPECT_EQ(stream->Finish().error_code(), grpc::StatusCode::CANCELLED) << "round " << round;
  }
  // The session still answers, on a stream and alone.
  auto context = Context();
  auto stream = stub_->StreamRelations(context.get());
  request.set_request_id(7);
  ASSERT_TRUE(stream->Write(request));
  stream->WritesDone();
  v1::StreamRelationsResponse r;
  ASSERT_TRUE(stream->Read(&r));
  EXPECT_EQ(r.request_id(), 7);
  EXPECT_EQ(Rows(r.offsets(), r.values()).size(), vertices.size());
  EXPECT_TRUE(stream->Finish().ok());
}

// A job with the request's defaults (arrays, no trace), its call ended and checked OK.
JobRun RunJob(v1::TopologyService::Stub& stub, grpc::ClientContext* context,
              const std::string& session, v1::Algorithm algorithm) {
  v1::RunJobRequest request;
  request.set_session_id(session);
  request.set_algorithm(algorithm);
  JobRun run = RunJob(stub, context, request);
  EXPECT_TRUE(run.status.ok()) << run.status.error_message();
  return run;
}

TEST_F(ServiceTest, JobsStreamAcceptedProgressArraysSummaryStats) {
  const Mesh mesh = OkValue(io::MakeSample("jittered:8"));
  const std::string mesh_id = LoadSample("jittered:8", 60);
  auto topo = OkValue(Topology::Build(mesh, OctreeBlocks(mesh.points, {.bucket_capacity = 60})));
  auto reference = OkValue(ExplicitStructure::Build(topo, {}));
  AlgorithmInput input;
  input.order = VertexOrder(*topo, mesh.point_fields[0].values);
  input.input_corners =
      std::make_shared<const std::vector<uint8_t>>(OkValue(InputCorners(*topo, mesh.tetrahedra)));
  input.scalars = mesh.point_fields[0].values;
  for (v1::Structure kind : {v1::STRUCTURE_EXPLICIT, v1::STRUCTURE_COMPACT, v1::STRUCTURE_ACTOPO}) {
    const std::string session = Open(mesh_id, kind, 2);
    // Digests only when asked: the explicit session's jobs go without them (the exact
    // comparison below then also says no "*_sha256" key came).
    const bool digests = kind != v1::STRUCTURE_EXPLICIT;
    for (Algorithm a : AllAlgorithms()) {
      if (ComparesFields(a)) continue;  // a list of fields: FieldJobs tests below
      input.algorithm = a;
      const std::string expected =
          Summarize(RunAlgorithm(*reference, input, {})->result, *topo, {.digests = digests})
              .dump();
      EXPECT_EQ(expected.find("_sha256") != std::string::npos,
                digests && a != Algorithm::kTopoRelations)
          << AlgorithmName(a);
      v1::RunJobRequest request;
      request.set_session_id(session);
      request.set_digests(digests);
      request.set_algorithm(static_cast<v1::Algorithm>(int(a) + 1));
      request.set_include_arrays(true);
      auto context = Context();
      const JobRun run = RunJob(*stub_, context.get(), request);
      ASSERT_TRUE(run.status.ok()) << run.status.error_message();
      ASSERT_GE(run.messages.size(), 3u);
      EXPECT_TRUE(run.messages.front().has_accepted());
      EXPECT_TRUE(run.messages.back().has_stats());
      const v1::RunJobResponse& summary = run.messages[run.messages.size() - 2];
      ASSERT_TRUE(summary.has_summary());
      std::string json;
      ASSERT_TRUE(
          google::protobuf::util::MessageToJsonString(summary.summary().result(), &json).ok());
      EXPECT_EQ(nlohmann::json::parse(json), nlohmann::json::parse(expected))
          << AlgorithmName(a) << " on structure " << int(kind);
      int progress = 0;
      std::set<std::string> arrays;
      for (const auto& m : run.messages) {
        progress += m.has_progress();
        if (m.has_chunk()) arrays.insert(m.chunk().array().name());
      }
      EXPECT_GT(progress, 0);
      if (a == Algorithm::kMorseSmale) {
        for (const char* name : {"critical_points/CellDimension", "critical_points/ManifoldSize",
                                 "separatrices/Offsets", "separatrices/SeparatrixType",
                                 "segmentation/MorseSmaleManifold"}) {
          EXPECT_TRUE(arrays.count(name)) << name;
        }
      }
      if (a == Algorithm::kCriticalPoints) {
        EXPECT_TRUE(arrays.count("critical_points/CriticalType"));
      }
      if (a == Algorithm::kTopologicalSimplification) {
        const std::string field = "simplified/" + mesh.point_fields[0].name;
        EXPECT_TRUE(arrays.count(field)) << field;
        EXPECT_TRUE(arrays.count(field + "_Order")) << field;
      }
      if (a == Algorithm::kPersistenceDiagram) {
        for (const char* name :
             {"diagram/Points", "diagram/Offsets", "diagram/Connectivity", "diagram/Coordinates",
              "diagram/PairIdentifier", "diagram/Persistence", "persistence_curve/NumberOfPairs"}) {
          EXPECT_TRUE(arrays.count(name)) << name;
        }
      }
    }
  }
}

TEST_F(ServiceTest, CancelJobStopsTheRun) {
  const std::string session = Open(LoadSample("jittered:60", 500), v1::STRUCTURE_COMPACT);
  v1::RunJobRequest request;
  request.set_session_id(session);
  request.set_algorithm(v1::ALGORITHM_TOPO_RELATIONS);
  auto context = Context();
  auto reader = stub_->RunJob(context.get(), request);
  v1::RunJobResponse accepted;
  ASSERT_TRUE(reader->Read(&accepted));
  ASSERT_TRUE(accepted.has_accepted());
  v1::CancelJobRequest cancel;
  cancel.set_job_id(accepted.accepted().job_id());
  v1::CancelJobResponse cancelled;
  ASSERT_TRUE(stub_->CancelJob(Context().get(), cancel, &cancelled).ok());
  // The job stops rather than running to the end and then saying CANCELLED: its progress never
  // reaches the end and no summary comes.
  v1::RunJobResponse message;
  double last_fraction = 0;
  while (reader->Read(&message)) {
    EXPECT_FALSE(message.has_summary());
    if (message.has_progress()) last_fraction = message.progress().fraction();
  }
  EXPECT_EQ(reader->Finish().error_code(), grpc::StatusCode::CANCELLED);
  EXPECT_LT(last_fraction, 1.0);
  EXPECT_EQ(stub_->CancelJob(Context().get(), cancel, &cancelled).error_code(),
            grpc::StatusCode::NOT_FOUND);
  // The session is usable again.
  request.set_algorithm(v1::ALGORITHM_CRITICAL_POINTS);
  auto again = Context();
  EXPECT_TRUE(RunJob(*stub_, again.get(), request).status.ok());
}

// A result larger than the stream's window (8 pieces of 1 MiB queued at most) goes out as the
// client reads it: whole, each array's pieces in order; a client that cancels mid-result gets
// CANCELLED, and the server's job thread stops sending (the fixture's server stops at the end).
TEST_F(ServiceTest, ALargeResultStreamsWholeAndStopsWhenItsClientGoes) {
  const std::string session = Open(LoadSample("wavelet:48", 1000), v1::STRUCTURE_COMPACT);
  v1::RunJobRequest request;
  request.set_session_id(session);
  request.set_algorithm(v1::ALGORITHM_MORSE_SMALE);
  request.set_include_arrays(true);
  auto context = Context();
  const JobRun run = RunJob(*stub_, context.get(), request);
  ASSERT_TRUE(run.status.ok()) << run.status.error_message();
  std::map<std::string, int64_t> received, total;
  int pieces = 0;
  for (const v1::RunJobResponse& m : run.messages) {
    if (!m.has_chunk()) continue;
    const std::string& name = m.chunk().array().name();
    EXPECT_EQ(m.chunk().offset(), received[name]) << name;
    received[name] += int64_t(m.chunk().array().data().size());
    total[name] = m.chunk().total_bytes();
    ++pieces;
  }
  EXPECT_EQ(received, total);
  EXPECT_GT(pieces, 8);
  EXPECT_GT(total["separatrices/Points"] + total["segmentation/MorseSmaleManifold"], 2 << 20);

  auto gone = Context();
  auto reader = stub_->RunJob(gone.get(), request);
  v1::RunJobResponse message;
  while (reader->Read(&message) && !message.has_chunk()) {
  }
  gone->TryCancel();
  while (reader->Read(&message)) {
  }
  EXPECT_EQ(reader->Finish().error_code(), grpc::StatusCode::CANCELLED);
  request.set_algorithm(v1::ALGORITHM_CRITICAL_POINTS);
  auto again = Context();
  EXPECT_TRUE(RunJob(*stub_, again.get(), request).status.ok());
}

TEST_F(ServiceTest, OfManyConcurrentRunJobsOnASessionExactlyOneRuns) {
  const std::string session = Open(LoadSample("jittered:60", 500), v1::STRUCTURE_ACTOPO);
  v1::RunJobRequest request;
  request.set_session_id(session);
  request.set_algorithm(v1::ALGORITHM_TOPO_RELATIONS);  // a few seconds: it outlives the race
  constexpr int kCalls = 24;
  struct Call {
    std::unique_ptr<grpc::ClientContext> context;
    std::unique_ptr<grpc::ClientReader<v1::RunJobResponse>> reader;
    std::string job_id;  // set when accepted
    grpc::Status status;
  };
  std::vector<Call> calls(kCalls);
  std::atomic<bool> go{false};
  std::vector<std::thread> threads;
  for (Call& call : calls) {
    threads.emplace_back([&] {
      while (!go.load()) std::this_thread::yield();
      call.context = Context();
      call.reader = stub_->RunJob(call.context.get(), request);
      v1::RunJobResponse first;
      if (call.reader->Read(&first) && first.has_accepted()) {
        call.job_id = first.accepted().job_id();
      } else {
        call.status = call.reader->Finish();
      }
    });
  }
  go = true;
  for (std::thread& t : threads) t.join();
  std::string winner;
  for (const Call& call : calls) {
    if (call.job_id.empty()) continue;
    ASSERT_TRUE(winner.empty()) << "two jobs accepted: " << winner << " and " << call.job_id;
    winner = call.job_id;
  }
  ASSERT_FALSE(winner.empty());
  v1::GetSessionRequest get;
  get.set_session_id(session);
  v1::GetSessionResponse described;
  ASSERT_TRUE(stub_->GetSession(Context().get(), get, &described).ok());
  EXPECT_EQ(described.session().running_job_id(), winner);
  for (const Call& call : calls) {
    if (!call.job_id.empty()) continue;
    EXPECT_EQ(call.status.error_code(), grpc::StatusCode::FAILED_PRECONDITION);
    EXPECT_NE(call.status.error_message().find(winner), std::string::npos)
        << call.status.error_message();
  }
  v1::CancelJobRequest cancel;
  cancel.set_job_id(winner);
  v1::CancelJobResponse cancelled;
  ASSERT_TRUE(stub_->CancelJob(Context().get(), cancel, &cancelled).ok());
  for (Call& call : calls) {
    if (call.job_id.empty()) continue;
    v1::RunJobResponse message;
    while (call.reader->Read(&message)) {
    }
    EXPECT_EQ(call.reader->Finish().error_code(), grpc::StatusCode::CANCELLED);
  }
  // The lease is released before the stream ends: the session takes the next job at once.
  ASSERT_TRUE(stub_->GetSession(Context().get(), get, &described).ok());
  EXPECT_EQ(described.session().running_job_id(), "");
  request.set_algorithm(v1::ALGORITHM_CRITICAL_POINTS);
  auto again = Context();
  EXPECT_TRUE(RunJob(*stub_, again.get(), request).status.ok());
}

TEST_F(ServiceTest, CancellingTheCallCancelsTheJob) {
  const std::string session = Open(LoadSample("jittered:60", 500), v1::STRUCTURE_ACTOPO);
  v1::RunJobRequest request;
  request.set_session_id(session);
  request.set_algorithm(v1::ALGORITHM_TOPO_RELATIONS);
  auto context = Context();
  auto reader = stub_->RunJob(context.get(), request);
  v1::RunJobResponse accepted;
  ASSERT_TRUE(reader->Read(&accepted));
  context->TryCancel();
  v1::RunJobResponse message;
  while (reader->Read(&message)) {
  }
  EXPECT_EQ(reader->Finish().error_code(), grpc::StatusCode::CANCELLED);
  // The job ends and frees the session for the next one.
  EXPECT_TRUE(actopo::testing::WaitUntil([&] {
    v1::GetSessionRequest get;
    get.set_session_id(session);
    v1::GetSessionResponse s;
    return stub_->GetSession(Context().get(), get, &s).ok() && s.session().running_job_id().empty();
  }));
  request.set_algorithm(v1::ALGORITHM_CRITICAL_POINTS);
  auto again = Context();
  EXPECT_TRUE(RunJob(*stub_, again.get(), request).status.ok());
}

TEST_F(ServiceTest, ConcurrentSessionsOnOneMesh) {
  const std::string mesh = LoadSample("jittered:12", 100);
  std::vector<std::string> sessions;
  for (v1::Structure kind : {v1::STRUCTURE_EXPLICIT, v1::STRUCTURE_COMPACT, v1::STRUCTURE_ACTOPO,
                             v1::STRUCTURE_ACTOPO}) {
    sessions.push_back(Open(mesh, kind));
  }
  std::vector<std::string> summaries(sessions.size());
  std::vector<std::thread> threads;
  for (size_t i = 0; i < sessions.size(); ++i) {
    threads.emplace_back([&, i] {
      auto context = Context();
      const JobRun run = RunJob(*stub_, context.get(), sessions[i], v1::ALGORITHM_MORSE_SMALE);
      for (const auto& m : run.messages) {
        if (m.has_summary()) summaries[i] = m.summary().result().DebugString();
      }
    });
  }
  for (auto& t : threads) t.join();
  for (const std::string& s : summaries) EXPECT_EQ(s, summaries[0]);
  EXPECT_FALSE(summaries[0].empty());
}

// A mesh is loaded without its edges and triangles; critical points never builds them; the first
// job and the first query that read them, at once on two sessions, build them once for both.
TEST_F(ServiceTest, EdgesAndTrianglesAreBuiltOnTheirFirstNeedOnly) {
  const Mesh mesh = OkValue(io::MakeSample("jittered:12"));
  const std::string mesh_id = LoadSample("jittered:12", 100);
  auto reference =
      OkValue(Topology::Build(mesh, OctreeBlocks(mesh.points, {.bucket_capacity = 100})));
  const auto describe = [&] {
    v1::GetMeshRequest get;
    get.set_mesh_id(mesh_id);
    v1::GetMeshResponse described;
    EXPECT_TRUE(stub_->GetMesh(Context().get(), get, &described).ok());
    return described.mesh();
  };
  const auto run = [&](const std::string& session, v1::Algorithm algorithm) {
    auto context = Context();
    RunJob(*stub_, context.get(), session, algorithm);
  };
  const v1::MeshInfo loaded = describe();
  EXPECT_FALSE(loaded.has_edges());
  EXPECT_FALSE(loaded.has_triangles());
  const std::string jobs = Open(mesh_id, v1::STRUCTURE_ACTOPO);
  const std::string queries = Open(mesh_id, v1::STRUCTURE_COMPACT);
  run(jobs, v1::ALGORITHM_CRITICAL_POINTS);
  EXPECT_FALSE(describe().has_edges());
  EXPECT_EQ(describe().bytes(), loaded.bytes());

  // Edge 7's vertices, asked while a gradient job on the other session needs the faces too.
  v1::GetRelationResponse edge;
  std::thread job([&] { run(jobs, v1::ALGORITHM_DISCRETE_GRADIENT); });
  {
    v1::GetRelationRequest q;
    q.set_session_id(queries);
    q.set_relation(v1::RELATION_EDGE_VERTICES);
    q.mutable_simplex()->set_id(7);
    const grpc::Status s = stub_->GetRelation(Context().get(), q, &edge);
    EXPECT_TRUE(s.ok()) << s.error_message();
  }
  job.join();
  const v1::MeshInfo built = describe();
  ASSERT_TRUE(built.has_edges());
  EXPECT_EQ(built.edges(), reference->num_edges());
  EXPECT_EQ(built.triangles(), reference->num_triangles());
  const TopologyBytes faces = reference->bytes();
  EXPECT_EQ(built.bytes() - loaded.bytes(), faces.edges + faces.triangles);
  ASSERT_EQ(edge.ids_size(), 2);
  const auto [a, b] = reference->edge(7);
  EXPECT_EQ(edge.ids(0), reference->vertex_input_id(a));
  EXPECT_EQ(edge.ids(1), reference->vertex_input_id(b));
}

// A job's progress says its phase: the first job on a mesh that reads faces reports "faces"
// (0 to 1) before the algorithm's "run", and its stats the faces' time; the next job, and one
// that needs no faces, "run" only, and no faces time.
TEST_F(ServiceTest, AJobReportsTheFacesItBuildsBeforeItsRun) {
  const std::string mesh_id = LoadSample("jittered:12", 100);
  const std::string session = Open(mesh_id, v1::STRUCTURE_ACTOPO);
  const auto phases = [&](v1::Algorithm algorithm) {
    auto context = Context();
    const JobRun job = RunJob(*stub_, context.get(), session, algorithm);
    std::vector<std::pair<std::string, double>> reports;
    double elapsed = 0;
    for (const v1::RunJobResponse& m : job.messages) {
      // The stats' faces time is there exactly when the job reported the phase.
      if (m.has_stats()) reports.emplace_back("stats: faces", m.stats().faces_seconds());
      if (!m.has_progress()) continue;
      reports.emplace_back(m.progress().phase(), m.progress().fraction());
      EXPECT_GE(m.progress().elapsed_seconds(), elapsed);
      elapsed = m.progress().elapsed_seconds();
    }
    return reports;
  };
  // Reports of the run only, then stats with no faces time.
  const auto only_run = [](std::vector<std::pair<std::string, double>> reports) {
    if (reports.empty() || reports.back() != std::pair<std::string, double>{"stats: faces", 0}) {
      return false;
    }
    reports.pop_back();
    return !reports.empty() && std::all_of(reports.begin(), reports.end(),
                                           [](const auto& r) { return r.first == "run"; });
  };
  EXPECT_TRUE(only_run(phases(v1::ALGORITHM_CRITICAL_POINTS)));

  auto first = phases(v1::ALGORITHM_DISCRETE_GRADIENT);
  ASSERT_EQ(first.back().first, "stats: faces");
  EXPECT_GT(first.back().second, 0.0);
  first.pop_back();
  const auto run =
      std::find_if(first.begin(), first.end(), [](const auto& r) { return r.first != "faces"; });
  ASSERT_GE(run - first.begin(), 2);
  EXPECT_EQ(first.front().second, 0.0);
  EXPECT_EQ((run - 1)->second, 1.0);
  EXPECT_TRUE(std::is_sorted(first.begin(), run));
  EXPECT_TRUE(run != first.end() &&
              std::all_of(run, first.end(), [](const auto& r) { return r.first == "run"; }));

  EXPECT_TRUE(only_run(phases(v1::ALGORITHM_DISCRETE_GRADIENT)));
}

TEST_F(ServiceTest, UploadRoundTrip) {
  const Mesh mesh = OkValue(io::MakeSample("jittered:4"));
  std::string bytes(reinterpret_cast<const char*>(mesh.points.data()),
                    mesh.points.size() * sizeof(double));
  bytes.append(reinterpret_cast<const char*>(mesh.tetrahedra.data()),
               mesh.tetrahedra.size() * sizeof(int32_t));
  const auto& f = mesh.point_fields[0];
  bytes.append(reinterpret_cast<const char*>(f.values.data()), f.values.size() * sizeof(double));
  v1::UploadMeshRequest header;
  auto* h = header.mutable_header();
  h->set_name("uploaded");
  h->set_num_vertices(mesh.num_vertices());
  h->set_num_tetrahedra(mesh.num_tetrahedra());
  h->set_points_dtype(v1::DATA_TYPE_FLOAT64);
  h->set_tetrahedra_dtype(v1::DATA_TYPE_INT32);
  auto* field = h->add_fields();
  field->set_name(f.name);
  field->set_dtype(v1::DATA_TYPE_FLOAT64);
  h->set_sha256(Sha256Hex(bytes));
  v1::UploadMeshResponse response;
  auto context = Context();
  auto writer = stub_->UploadMesh(context.get(), &response);
  ASSERT_TRUE(writer->Write(header));
  for (size_t offset = 0; offset < bytes.size(); offset += 1000) {
    v1::UploadMeshRequest chunk;
    chunk.set_chunk(bytes.substr(offset, 1000));
    ASSERT_TRUE(writer->Write(chunk));
  }
  writer->WritesDone();
  const grpc::Status s = writer->Finish();
  ASSERT_TRUE(s.ok()) << s.error_message();
  EXPECT_EQ(response.mesh().vertices(), 64);
  EXPECT_EQ(response.mesh().tetrahedra(), 162);
  EXPECT_EQ(response.mesh().source(), "upload");
  EXPECT_EQ(response.mesh().fields(0).name(), f.name);
}

TEST_F(ServiceTest, LimitsAreEnforced) {
  options_.max_sessions = 2;
  options_.max_meshes = 2;
  StartServer();
  const std::string mesh = LoadSample("jittered:5");
  LoadSample("jittered:4");
  v1::LoadMeshRequest third;
  third.set_sample("jittered:3");
  v1::LoadMeshResponse loaded;
  EXPECT_EQ(stub_->LoadMesh(Context().get(), third, &loaded).error_code(),
            grpc::StatusCode::RESOURCE_EXHAUSTED);
  Open(mesh, v1::STRUCTURE_COMPACT);
  Open(mesh, v1::STRUCTURE_COMPACT);
  v1::OpenSessionRequest open;
  open.set_mesh_id(mesh);
  v1::OpenSessionResponse opened;
  const grpc::Status s = stub_->OpenSession(Context().get(), open, &opened);
  EXPECT_EQ(s.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED);
  EXPECT_NE(s.error_message().find("maximum of 2 sessions"), std::string::npos);
}

TEST_F(ServiceTest, MemoryBudgetRefusesWhatWouldNotFit) {
  options_.memory_budget_bytes = int64_t(20) << 20;
  StartServer();
  v1::LoadMeshRequest big;
  big.set_sample("jittered:100");  // about 6M tetrahedra
  v1::LoadMeshResponse loaded;
  const grpc::Status s = stub_->LoadMesh(Context().get(), big, &loaded);
  EXPECT_EQ(s.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED);
  EXPECT_NE(s.error_message().find("memory budget"), std::string::npos);
  // Small ones still fit (jittered:24, 73K tetrahedra, estimated at about 7 MB); an explicit
  // session on it, all relations stored (estimated at about 29 MB), does not.
  const std::string mesh = LoadSample("jittered:24");
  v1::OpenSessionRequest open;
  open.set_mesh_id(mesh);
  open.set_structure(v1::STRUCTURE_EXPLICIT);
  v1::OpenSessionResponse opened;
  EXPECT_EQ(stub_->OpenSession(Context().get(), open, &opened).error_code(),
            grpc::StatusCode::RESOURCE_EXHAUSTED);
}

// Refused before anything is read or made: a file's header, a sample's name and an upload's
// header give the size. The file below claims a mesh it does not hold; were it read, VTK would
// fail on it with INVALID_ARGUMENT instead.
TEST_F(ServiceTest, MemoryBudgetRefusesBeforeReading) {
  options_.memory_budget_bytes = int64_t(64) << 20;
  StartServer();
  std::ofstream(data_dir_ / "claims.vtu")
      << "<VTKFile type=\"UnstructuredGrid\"><UnstructuredGrid>"
         "<Piece NumberOfPoints=\"2000000\" NumberOfCells=\"10000000\">";
  v1::LoadMeshRequest file;
  file.set_path("claims.vtu");
  v1::LoadMeshResponse loaded;
  grpc::Status s = stub_->LoadMesh(Context().get(), file, &loaded);
  EXPECT_EQ(s.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED) << s.error_message();
  EXPECT_NE(s.error_message().find("2000000 vertices and 10000000 tetrahedra by its header"),
            std::string::npos)
      << s.error_message();
  v1::LoadMeshRequest sample;
  sample.set_sample("wavelet:512");  // 670M tetrahedra: refused at once, nothing made
  s = stub_->LoadMesh(Context().get(), sample, &loaded);
  EXPECT_EQ(s.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED) << s.error_message();
  EXPECT_NE(s.error_message().find("sample 'wavelet:512'"), std::string::npos);
  // An upload is refused at its header, before any chunk.
  auto context = Context();
  v1::UploadMeshResponse uploaded;
  auto writer = stub_->UploadMesh(context.get(), &uploaded);
  v1::UploadMeshRequest header;
  header.mutable_header()->set_num_vertices(2000000);
  header.mutable_header()->set_num_tetrahedra(10000000);
  header.mutable_header()->set_points_dtype(v1::DATA_TYPE_FLOAT64);
  header.mutable_header()->set_tetrahedra_dtype(v1::DATA_TYPE_INT32);
  header.mutable_header()->set_sha256(std::string(64, '0'));
  writer->Write(header);
  writer->WritesDone();
  s = writer->Finish();
  EXPECT_EQ(s.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED) << s.error_message();
  EXPECT_NE(s.error_message().find("uploading 2000000 vertices"), std::string::npos);
  EXPECT_EQ(server_->memory_budget_used_bytes(), 0);
}

TEST_F(ServiceTest, TokenIsRequiredWhenSet) {
  options_.token = "s3cret";
  StartServer();
  v1::GetServerInfoResponse info;
  const grpc::Status denied = stub_->GetServerInfo(Context().get(), {}, &info);
  EXPECT_EQ(denied.error_code(), grpc::StatusCode::UNAUTHENTICATED);
  token_ = "wrong";
  EXPECT_EQ(stub_->GetServerInfo(Context().get(), {}, &info).error_code(),
            grpc::StatusCode::UNAUTHENTICATED);
  token_ = "s3cret";
  EXPECT_TRUE(stub_->GetServerInfo(Context().get(), {}, &info).ok());
}

TEST_F(ServiceTest, DrainingRefusesNewWorkAndCancelsJobs) {
  const std::string session = Open(LoadSample("jittered:60", 500), v1::STRUCTURE_COMPACT);
  v1::RunJobRequest request;
  request.set_session_id(session);
  request.set_algorithm(v1::ALGORITHM_TOPO_RELATIONS);
  auto context = Context();
  auto reader = stub_->RunJob(context.get(), request);
  v1::RunJobResponse message;
  ASSERT_TRUE(reader->Read(&message));
  server_->Drain();
  while (reader->Read(&message)) {
  }
  EXPECT_EQ(reader->Finish().error_code(), grpc::StatusCode::CANCELLED);
  v1::GetServerInfoResponse info;
  const grpc::Status s = stub_->GetServerInfo(Context().get(), {}, &info);
  EXPECT_EQ(s.error_code(), grpc::StatusCode::UNAVAILABLE);
  EXPECT_NE(s.error_message().find("shutting down"), std::string::npos);
}

}  // namespace
}  // namespace actopo::service

namespace actopo::service {
namespace {

int FreePort() {
  const int fd = socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  bind(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr);
  socklen_t len = sizeof addr;
  getsockname(fd, reinterpret_cast<sockaddr*>(&addr), &len);
  close(fd);
  return ntohs(addr.sin_port);
}

std::string HttpGet(int port, const std::string& path) {
  const int fd = socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_port = htons(port);
  addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  if (connect(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr) != 0) {
    close(fd);
    return "";
  }
  const std::string request = "GET " + path + " HTTP/1.0\r\nHost: localhost\r\n\r\n";
  (void)!write(fd, request.data(), request.size());
  std::string response;
  char buf[4096];
  for (ssize_t n; (n = read(fd, buf, sizeof buf)) > 0;) response.append(buf, n);
  close(fd);
  return response;
}

TEST_F(ServiceTest, PrometheusMetrics) {
  options_.metrics_port = FreePort();
  StartServer();
  ASSERT_EQ(server_->metrics_port(), options_.metrics_port);
  const std::string mesh = LoadSample("jittered:5");
  const std::string session = Open(mesh, v1::STRUCTURE_ACTOPO);
  v1::RunJobRequest request;
  request.set_session_id(session);
  request.set_algorithm(v1::ALGORITHM_CRITICAL_POINTS);
  auto context = Context();
  auto reader = stub_->RunJob(context.get(), request);
  v1::RunJobResponse m;
  while (reader->Read(&m)) {
  }
  ASSERT_TRUE(reader->Finish().ok());
  v1::GetMeshRequest missing;
  missing.set_mesh_id("mesh-none");
  v1::GetMeshResponse out;
  stub_->GetMesh(Context().get(), missing, &out);
  v1::CreateUploadRequest upload;
  v1::UploadFileInfo* file = upload.add_files();
  file->set_path("a.vtu");
  file->set_size(1234);
  file->set_sha256(std::string(64, 'a'));
  v1::CreateUploadResponse created;
  ASSERT_TRUE(stub_->CreateUpload(Context().get(), upload, &created).ok());
  const std::string text = HttpGet(options_.metrics_port, "/metrics");
  for (const char* expected :
       {"actopo_requests_total{code=\"0\",rpc=\"LoadMesh\"} 1",
        "actopo_requests_total{code=\"5\",rpc=\"GetMesh\"} 1",
        "actopo_requests_total{code=\"0\",rpc=\"RunJob\"} 1",
        "actopo_job_duration_seconds_count{algorithm=\"critical-points\",structure=\"actopo\"} 1",
        "actopo_sessions 1", "actopo_meshes 1", "actopo_buffer_hits_total",
        "actopo_consumer_wait_seconds_total", "actopo_process_resident_bytes",
        "actopo_process_heap_bytes", "actopo_memory_budget_limit_bytes 4294967296",
        "actopo_uploads 1", "actopo_upload_bytes 1234"}) {
    EXPECT_NE(text.find(expected), std::string::npos) << expected << "\n" << text.substr(0, 2000);
  }
  // Low cardinality: no ids in labels.
  EXPECT_EQ(text.find("session-"), std::string::npos);
  EXPECT_EQ(text.find("mesh-"), std::string::npos);
  EXPECT_EQ(text.find("\"upload-"), std::string::npos);  // an id as a label value
}

}  // namespace
}  // namespace actopo::service
