// Relation queries: single, batch (split over the shared server's max_batch_size of 64) and
// streams, with their errors.
#include <latch>
#include <stdexcept>
#include <thread>

#include "tests/testing/fixture.h"

namespace actopo::client::testing {
namespace {

using absl::StatusCode;

class RelationsTest : public ServerTest {
 protected:
  void SetUp() override {
    ServerTest::SetUp();
    if (IsSkipped() || HasFatalFailure()) return;
    mesh_ = LoadSample("jittered:6", 50);  // 216 vertices, 750 tetrahedra, several blocks
    session_ = Open(mesh_, {.structure = Structure::kActopo});
  }

  std::vector<int64_t> Single(const std::string& relation, const Simplex& simplex) {
    absl::StatusOr<std::vector<int64_t>> ids = client().Relation(session_, relation, simplex);
    EXPECT_TRUE(ids.ok()) << relation << ": " << ids.status();
    return ids.ok() ? *ids : std::vector<int64_t>{};
  }

  std::string mesh_, session_;
};

TEST_F(RelationsTest, SingleByIdAndByVertices) {
  const std::vector<int64_t> tet = Single("tetrahedron_vertices", 0);
  ASSERT_EQ(tet.size(), 4u);
  EXPECT_TRUE(std::is_sorted(tet.begin(), tet.end()));
  // Each vertex of tetrahedron 0 has it in its star.
  for (int64_t v : tet) {
    const std::vector<int64_t> star = Single("vertex_star", v);
    EXPECT_TRUE(std::binary_search(star.begin(), star.end(), 0)) << v;
  }
  // Its edges, with their vertex tuples: (v0v1), (v0v2), (v0v3), (v1v2), (v1v3), (v2v3).
  absl::StatusOr<RelationResult> edges =
      client().RelationWithVertices(session_, "tetrahedron_edges", 0);
  ASSERT_OK(edges);
  ASSERT_EQ(edges->ids.size(), 6u);
  ASSERT_EQ(edges->vertices.size(), 12u);
  EXPECT_EQ(edges->vertices[0], tet[0]);
  EXPECT_EQ(edges->vertices[1], tet[1]);
  EXPECT_EQ(edges->vertices[10], tet[2]);
  EXPECT_EQ(edges->vertices[11], tet[3]);
  // An edge by id and by its vertices in any order.
  EXPECT_EQ(Single("edge_star", edges->ids[0]),
            Single("edge_star", Simplex::Vertices({tet[1], tet[0]})));
  EXPECT_EQ(Single("edge_vertices", edges->ids[5]), (std::vector<int64_t>{tet[2], tet[3]}));
  // A triangle by its vertices; the plain call sends no vertex tuples back.
  const std::vector<int64_t> star =
      Single("triangle_star", Simplex::Vertices({tet[2], tet[0], tet[1]}));
  EXPECT_TRUE(std::find(star.begin(), star.end(), 0) != star.end());
  absl::StatusOr<RelationResult> plain = client().RelationWithVertices(session_, "vertex_star", 0);
  ASSERT_OK(plain);
  EXPECT_TRUE(plain->vertices.empty());
  // Boundary predicates are one 0/1 value; vertex 0 is a corner of the lattice.
  EXPECT_EQ(Single("vertex_on_boundary", 0), (std::vector<int64_t>{1}));
  // Names are forgiving about case and '-'.
  EXPECT_EQ(Single("Vertex-Star", 0), Single("vertex_star", 0));
}

TEST_F(RelationsTest, SingleErrors) {
  EXPECT_TRUE(HasError(client().Relation(session_, "vertex_star", 216), StatusCode::kOutOfRange,
                       "vertex id 216"));
  EXPECT_TRUE(HasError(client().Relation(session_, "tetrahedron_vertices", -3),
                       StatusCode::kOutOfRange, "tetrahedron id -3"));
  EXPECT_TRUE(HasError(client().Relation(session_, "triangle_star", Simplex::Vertices({0, 1})),
                       StatusCode::kInvalidArgument, "a triangle has 3 vertices, got 2"));
  EXPECT_TRUE(HasError(client().Relation(session_, "triangle_star", Simplex::Vertices({0, 1, 215})),
                       StatusCode::kNotFound, "is not a triangle"));
  EXPECT_TRUE(HasError(client().Relation(session_, "edge_star", Simplex::Vertices({0, 1000})),
                       StatusCode::kOutOfRange, "vertex id 1000"));
  EXPECT_TRUE(HasError(client().Relation("session-guess", "vertex_star", 0), StatusCode::kNotFound,
                       "session-guess"));
}

TEST_F(RelationsTest, BatchEqualsSinglesAcrossSplits) {
  std::vector<int64_t> ids;
  for (int64_t v = 215; v >= 0; v -= 1) ids.push_back(v);  // 216 ids: 4 requests of <= 64
  for (const char* relation : {"vertex_edges", "vertex_link", "vertex_on_boundary"}) {
    absl::StatusOr<RelationCsr> batch = client().RelationBatch(session_, relation, ids);
    ASSERT_OK(batch);
    ASSERT_EQ(batch->size(), ids.size());
    EXPECT_EQ(batch->offsets.back(), int64_t(batch->values.size()));
    for (size_t i = 0; i < ids.size(); i += 7) {
      const std::span<const int64_t> row = (*batch)[i];
      EXPECT_EQ(std::vector<int64_t>(row.begin(), row.end()), Single(relation, ids[i]))
          << relation << " of " << ids[i];
    }
  }
}

TEST_F(RelationsTest, BatchByVertexTuples) {
  std::vector<int64_t> edges(100), tuples;
  for (int64_t e = 0; e < 100; ++e) {
    edges[e] = e;
    const std::vector<int64_t> v = Single("edge_vertices", e);
    tuples.insert(tuples.end(), {v[1], v[0]});  // any order
  }
  absl::StatusOr<RelationCsr> by_ids = client().RelationBatch(session_, "edge_triangles", edges);
  absl::StatusOr<RelationCsr> by_tuples =
      client().RelationBatchByVertices(session_, "edge_triangles", tuples, 2);
  ASSERT_OK(by_ids);
  ASSERT_OK(by_tuples);
  EXPECT_EQ(by_ids->offsets, by_tuples->offsets);
  EXPECT_EQ(by_ids->values, by_tuples->values);
}

TEST_F(RelationsTest, BatchErrors) {
  const std::vector<int64_t> ids = {0, 1, 5000};
  EXPECT_TRUE(HasError(client().RelationBatch(session_, "vertex_star", ids),
                       StatusCode::kOutOfRange, "5000"));
  EXPECT_TRUE(
      HasError(client().RelationBatch("session-guess", "vertex_star", ids), StatusCode::kNotFound));
}

TEST_F(RelationsTest, StreamedBatchErrorNamesTheInputPosition) {
  std::vector<int64_t> ids(200);
  for (int64_t i = 0; i < 200; ++i) ids[i] = i;
  ids[130] = 5000;  // in the third request of 64
  EXPECT_TRUE(HasError(client().RelationBatch(session_, "vertex_star", ids),
                       StatusCode::kOutOfRange, "simplex 130 of the input"));
}

TEST_F(RelationsTest, StreamBatchesByHandKeepItemErrors) {
  absl::StatusOr<std::unique_ptr<RelationStream>> opened = client().OpenRelationStream();
  ASSERT_OK(opened);
  RelationStream& stream = **opened;
  const std::vector<int64_t> ids = {4, 9, -3, 17};
  ASSERT_OK(stream.WriteBatch(1, session_, "vertex_edges", ids));
  const std::vector<int64_t> edge = Single("edge_vertices", 3);
  ASSERT_OK(stream.WriteBatch(2, session_, "edge_triangles", edge, 2));
  ASSERT_OK(stream.WriteBatch(3, "session-guess", "vertex_edges", ids));
  EXPECT_TRUE(HasError(stream.WriteBatch(4, session_, "edge_triangles", ids, 3),
                       StatusCode::kInvalidArgument, "tuples of 3"));
  ASSERT_OK(stream.WritesDone());
  std::optional<StreamItem> item = stream.Read();
  ASSERT_TRUE(item.has_value());
  ASSERT_OK(item->ids);
  ASSERT_EQ(item->rows.size(), ids.size());
  ASSERT_EQ(item->item_errors.size(), 1u);
  EXPECT_EQ(item->item_errors[0].index, 2);
  EXPECT_TRUE(HasError(item->item_errors[0].status, StatusCode::kOutOfRange, "ids[2]"));
  EXPECT_TRUE(item->rows[2].empty());
  for (size_t i : {0, 1, 3}) {
    EXPECT_EQ(std::vector<int64_t>(item->rows[i].begin(), item->rows[i].end()),
              Single("vertex_edges", ids[i]));
  }
  item = stream.Read();
  ASSERT_TRUE(item.has_value());
  ASSERT_EQ(item->rows.size(), 1u);
  EXPECT_EQ(std::vector<int64_t>(item->rows[0].begin(), item->rows[0].end()),
            Single("edge_triangles", 3));
  item = stream.Read();
  ASSERT_TRUE(item.has_value());
  EXPECT_TRUE(HasError(item->ids.status(), StatusCode::kNotFound, "session-guess"));
  EXPECT_FALSE(stream.Read().has_value());
  EXPECT_OK(stream.Finish());
}

TEST_F(RelationsTest, StreamKeepsGoingAfterBadItems) {
  const std::vector<int64_t> ids = {3, -1, 4, 99999, 5};
  std::vector<StreamItem> items;
  ASSERT_OK(client().StreamRelations(session_, "vertex_neighbors", ids,
                                     [&](StreamItem item) { items.push_back(std::move(item)); }));
  ASSERT_EQ(items.size(), ids.size());
  for (size_t i = 0; i < ids.size(); ++i) {
    EXPECT_EQ(items[i].request_id, int64_t(i));
    if (ids[i] < 0 || ids[i] > 1000) {
      EXPECT_TRUE(HasError(items[i].ids.status(), StatusCode::kOutOfRange, std::to_string(ids[i])));
    } else {
      ASSERT_OK(items[i].ids);
      EXPECT_EQ(*items[i].ids, Single("vertex_neighbors", ids[i]));
    }
  }
}

TEST_F(RelationsTest, StreamOfManyEqualsTheBatch) {
  std::vector<int64_t> ids;
  for (int repeat = 0; repeat < 10; ++repeat) {
    for (int64_t v = 0; v < 216; ++v) ids.push_back(v);
  }
  absl::StatusOr<RelationCsr> batch = client().RelationBatch(session_, "vertex_star", ids);
  ASSERT_OK(batch);
  size_t seen = 0;
  ASSERT_OK(client().StreamRelations(session_, "vertex_star", ids, [&](StreamItem item) {
    ASSERT_OK(item.ids);
    const std::span<const int64_t> row = (*batch)[size_t(item.request_id)];
    EXPECT_EQ(*item.ids, std::vector<int64_t>(row.begin(), row.end()));
    ++seen;
  }));
  EXPECT_EQ(seen, ids.size());
}

TEST_F(RelationsTest, StreamCallbackMayThrow) {
  const std::vector<int64_t> ids(5000, 0);
  int seen = 0;
  EXPECT_THROW(client().StreamRelations(session_, "vertex_star", ids,
                                        [&](StreamItem) {
                                          if (++seen == 10) throw std::runtime_error("enough");
                                        }),
               std::runtime_error);
  EXPECT_EQ(seen, 10);
  EXPECT_OK(client().Relation(session_, "vertex_star", 0));  // the client still works
}

TEST_F(RelationsTest, StreamOfVertexTuples) {
  const std::vector<int64_t> tet = Single("tetrahedron_vertices", 0);
  const std::vector<Simplex> simplices = {Simplex::Vertices({tet[0], tet[1], tet[2]}),
                                          Simplex::Vertices({tet[0], tet[1]}), 0};
  std::vector<StreamItem> items;
  ASSERT_OK(client().StreamRelations(session_, "triangle_star", simplices,
                                     [&](StreamItem item) { items.push_back(std::move(item)); }));
  ASSERT_EQ(items.size(), 3u);
  EXPECT_OK(items[0].ids);
  EXPECT_TRUE(HasError(items[1].ids.status(), StatusCode::kInvalidArgument, "3 vertices"));
  EXPECT_OK(items[2].ids);  // triangle id 0
}

TEST_F(RelationsTest, StreamDrivenByHand) {
  absl::StatusOr<std::unique_ptr<RelationStream>> opened = client().OpenRelationStream();
  ASSERT_OK(opened);
  RelationStream& stream = **opened;
  // Requests written on one thread, answers read on this one; sessions and relations mixed.
  const std::string other = Open(mesh_, {.structure = Structure::kCompact});
  std::thread writer([&] {
    for (int64_t i = 0; i < 200; ++i) {
      EXPECT_OK(stream.Write(1000 + i, i % 2 ? session_ : other,
                             i % 3 ? "vertex_star" : "vertex_edges", i));
    }
    EXPECT_OK(stream.Write(5, "session-guess", "vertex_star", 0));
    EXPECT_OK(stream.WritesDone());
    EXPECT_TRUE(
        HasError(stream.Write(6, session_, "vertex_star", 0), StatusCode::kFailedPrecondition));
  });
  EXPECT_TRUE(HasError(stream.Write(1, session_, "vertex_starz", 0), StatusCode::kInvalidArgument));
  int64_t expected = 1000;
  while (std::optional<StreamItem> item = stream.Read()) {
    if (item->request_id == 5) {
      EXPECT_TRUE(HasError(item->ids.status(), StatusCode::kNotFound, "session-guess"));
      continue;
    }
    EXPECT_EQ(item->request_id, expected);  // answers come in request order
    const int64_t i = item->request_id - 1000;
    ASSERT_OK(item->ids);
    EXPECT_EQ(*item->ids, Single(i % 3 ? "vertex_star" : "vertex_edges", i));
    ++expected;
  }
  writer.join();
  EXPECT_EQ(expected, 1200);
  EXPECT_OK(stream.Finish());
  EXPECT_OK(stream.Finish());  // the same answer again
}

TEST_F(RelationsTest, StreamAbandonedEarlyEnds) {
  absl::StatusOr<std::unique_ptr<RelationStream>> opened = client().OpenRelationStream();
  ASSERT_OK(opened);
  ASSERT_OK((*opened)->Write(1, session_, "vertex_star", 0));
  ASSERT_TRUE((*opened)->Read().has_value());
  ASSERT_OK((*opened)->Write(2, session_, "vertex_star", 1));
  // Finish without reading the second answer: the call is cancelled, not waited for. The server
  // cannot have ended it first: it ends a stream only after the client's last write.
  EXPECT_TRUE(HasError((*opened)->Finish(), StatusCode::kCancelled));
  // Cancel from another thread ends a Read that nothing else would end, whether the Read has
  // begun to wait when the Cancel comes or not (which a test cannot see): the same outcome.
  absl::StatusOr<std::unique_ptr<RelationStream>> idle = client().OpenRelationStream();
  ASSERT_OK(idle);
  std::latch reading(1);
  std::thread canceller([&] {
    reading.wait();
    (*idle)->Cancel();
  });
  reading.count_down();
  EXPECT_FALSE((*idle)->Read().has_value());  // nothing was asked: only Cancel ends this
  canceller.join();
  EXPECT_TRUE(HasError((*idle)->Finish(), StatusCode::kCancelled));
  // Destroying an unfinished stream is fine too.
  absl::StatusOr<std::unique_ptr<RelationStream>> dropped = client().OpenRelationStream();
  ASSERT_OK(dropped);
  ASSERT_OK((*dropped)->Write(1, session_, "vertex_star", 0));
}

}  // namespace
}  // namespace actopo::client::testing
