// Uploads: a lattice made here goes up as int32 and int64 tetrahedra, in one or many chunks.
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

#include "tests/testing/fixture.h"

namespace actopo::client::testing {
namespace {

using absl::StatusCode;

// An n^3 lattice of the unit cube, each cell split into 6 positively oriented tetrahedra around
// its main diagonal, with a tie-free linear field.
struct Lattice {
  explicit Lattice(int n) {
    auto id = [n](int i, int j, int k) { return int64_t(i) + n * (int64_t(j) + int64_t(n) * k); };
    for (int k = 0; k < n; ++k) {
      for (int j = 0; j < n; ++j) {
        for (int i = 0; i < n; ++i) {
          const double x = double(i) / (n - 1), y = double(j) / (n - 1), z = double(k) / (n - 1);
          points.insert(points.end(), {x, y, z});
          height.push_back(z + 0.1 * y + 0.01 * x);
        }
      }
    }
    constexpr std::array<std::array<int, 3>, 6> kAxes = {
        {{0, 1, 2}, {0, 2, 1}, {1, 0, 2}, {1, 2, 0}, {2, 0, 1}, {2, 1, 0}}};
    for (int k = 0; k + 1 < n; ++k) {
      for (int j = 0; j + 1 < n; ++j) {
        for (int i = 0; i + 1 < n; ++i) {
          for (const auto& axes : kAxes) {
            int c[3] = {i, j, k};
            std::array<int64_t, 4> tet;
            tet[0] = id(c[0], c[1], c[2]);
            for (int step = 0; step < 3; ++step) {
              ++c[axes[step]];
              tet[step + 1] = id(c[0], c[1], c[2]);
            }
            if (Volume(tet) < 0) std::swap(tet[2], tet[3]);
            tetrahedra.insert(tetrahedra.end(), tet.begin(), tet.end());
          }
        }
      }
    }
    tetrahedra32.assign(tetrahedra.begin(), tetrahedra.end());
  }

  double Volume(const std::array<int64_t, 4>& t) const {
    double d[3][3];
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 3; ++c) d[r][c] = points[3 * t[r + 1] + c] - points[3 * t[0] + c];
    }
    return d[0][0] * (d[1][1] * d[2][2] - d[1][2] * d[2][1]) -
           d[0][1] * (d[1][0] * d[2][2] - d[1][2] * d[2][0]) +
           d[0][2] * (d[1][0] * d[2][1] - d[1][1] * d[2][0]);
  }

  int64_t vertices() const { return int64_t(points.size() / 3); }
  int64_t cells() const { return int64_t(tetrahedra.size() / 4); }

  std::vector<double> points, height;
  std::vector<int64_t> tetrahedra;
  std::vector<int32_t> tetrahedra32;
};

class UploadTest : public ServerTest {
 protected:
  std::string Keep(const absl::StatusOr<MeshInfo>& mesh) {
    EXPECT_TRUE(mesh.ok()) << mesh.status();
    if (!mesh.ok()) return "";
    meshes_.push_back(mesh->mesh_id);
    return mesh->mesh_id;
  }
};

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
