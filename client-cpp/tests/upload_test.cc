// Uploads: a lattice made here goes up as int32 and int64 tetrahedra, in one or many chunks.
#include <algorithm>
#include <cmath>
#include <limits>

#include "tests/testing/fixture.h"
#include "tests/testing/lattice.h"

namespace actopo::client::testing {
namespace {

using absl::StatusCode;

class UploadTest : public ServerTest {};

TEST_F(UploadTest, Int32AndInt64RoundTrip) {
  const Lattice lattice(5);
  for (bool wide : {false, true}) {
    SCOPED_TRACE(wide ? "int64" : "int32");
    // Tiny chunks: every chunk boundary straddles the arrays somewhere.
    const UploadOptions options{.name = "lattice", .chunk_bytes = 1000};
    absl::StatusOr<MeshInfo> mesh =
        wide ? client().UploadMesh(lattice.points, lattice.tetrahedra, {{"height", lattice.height}},
                                   options)
             : client().UploadMesh(lattice.points, lattice.tetrahedra32,
                                   {{"height", lattice.height}}, options);
    const std::string id = Keep(mesh);
    ASSERT_FALSE(id.empty());
    EXPECT_EQ(mesh->name, "lattice");
    EXPECT_EQ(mesh->source, "upload");
    EXPECT_EQ(mesh->vertices, 125);
    EXPECT_EQ(mesh->tetrahedra, 6 * 64);
    absl::StatusOr<MeshInfo> counted = client().GetMesh(id, /*count_faces=*/true);
    ASSERT_TRUE(counted.ok() && counted->edges && counted->triangles) << counted.status();
    EXPECT_EQ(counted->vertices - *counted->edges + *counted->triangles - counted->tetrahedra,
              1);  // a ball
    ASSERT_EQ(mesh->fields.size(), 1u);
    EXPECT_EQ(mesh->fields[0].name, "height");
    EXPECT_EQ(mesh->fields[0].dtype, DataType::kFloat64);
    EXPECT_DOUBLE_EQ(mesh->fields[0].min, 0.0);
    EXPECT_NEAR(mesh->fields[0].max, 1.11, 1e-12);

    const std::string session = Open(id, {.structure = Structure::kExplicit});
    std::vector<int64_t> all(size_t(lattice.cells()));
    for (size_t t = 0; t < all.size(); ++t) all[t] = int64_t(t);
    absl::StatusOr<RelationCsr> tets = client().RelationBatch(session, "tetrahedron_vertices", all);
    ASSERT_OK(tets);
    for (size_t t = 0; t < all.size(); ++t) {
      std::vector<int64_t> input(lattice.tetrahedra.begin() + 4 * t,
                                 lattice.tetrahedra.begin() + 4 * t + 4);
      std::sort(input.begin(), input.end());
      ASSERT_EQ(std::vector<int64_t>((*tets)[t].begin(), (*tets)[t].end()), input) << t;
    }
    absl::StatusOr<JobResult> result = client().RunJob(session, "critical-points");
    ASSERT_OK(result);
    const nlohmann::json counts = nlohmann::json::parse(result->summary_json)["counts"];
    EXPECT_EQ(counts["minimum"], 1);
    EXPECT_EQ(counts["maximum"], 1);
    EXPECT_EQ(counts["saddle1"], 0);
    EXPECT_EQ(counts["saddle2"], 0);
  }
}

TEST_F(UploadTest, ManyMegabytesInDefaultChunks) {
  const Lattice lattice(30);  // 27,000 vertices, 146,334 tetrahedra: about 3 MiB
  absl::StatusOr<MeshInfo> mesh =
      client().UploadMesh(lattice.points, lattice.tetrahedra32, {{"height", lattice.height}},
                          {.partition = {.block_size = 2000}});
  ASSERT_FALSE(Keep(mesh).empty());
  EXPECT_EQ(mesh->name, "upload");
  EXPECT_EQ(mesh->vertices, lattice.vertices());
  EXPECT_EQ(mesh->tetrahedra, lattice.cells());
  EXPECT_EQ(mesh->block_size, 2000);
  absl::StatusOr<MeshInfo> counted = client().GetMesh(mesh->mesh_id, /*count_faces=*/true);
  ASSERT_TRUE(counted.ok() && counted->edges && counted->triangles) << counted.status();
  EXPECT_EQ(counted->vertices - *counted->edges + *counted->triangles - counted->tetrahedra, 1);
}

TEST_F(UploadTest, ServerRejectionsKeepTheirCodes) {
  const Lattice lattice(3);
  std::vector<int32_t> tets = lattice.tetrahedra32;
  tets[5] = 27;  // one past the last vertex
  EXPECT_TRUE(
      HasError(client().UploadMesh(lattice.points, tets), StatusCode::kOutOfRange, "vertex id 27"));
  tets[5] = tets[4];
  EXPECT_TRUE(HasError(client().UploadMesh(lattice.points, tets), StatusCode::kInvalidArgument,
                       "repeats vertex"));
  // A NaN scalar uploads, but no session opens on it.
  std::vector<double> field = lattice.height;
  field[3] = std::numeric_limits<double>::quiet_NaN();
  const std::string id =
      Keep(client().UploadMesh(lattice.points, lattice.tetrahedra32, {{"bad", field}}));
  ASSERT_FALSE(id.empty());
  EXPECT_TRUE(HasError(client().OpenSession(id, {.scalar = "bad"}), StatusCode::kInvalidArgument,
                       "non-finite value nan"));
}

}  // namespace
}  // namespace actopo::client::testing
