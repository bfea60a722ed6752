#include "server/io/vtk_reader.h"

#include <algorithm>
#include <atomic>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "gmock/gmock.h"
#include "gtest/gtest.h"
#include "server/io/test_data.h"

namespace actopo::io {
namespace {

using testing::DataDir;
using testing::DataTest;
using ::testing::ElementsAre;
using ::testing::HasSubstr;
using testing::MakeTempDir;
using testing::SignedVolume6;

std::vector<std::string> FieldNames(const Mesh& mesh) {
  std::vector<std::string> names;
  for (const PointField& f : mesh.point_fields) names.push_back(f.name);
  return names;
}

void WriteText(const std::filesystem::path& path, const std::string& text) {
  std::ofstream out(path, std::ios::binary);
  out << text;
}

struct Expected {
  std::string file;
  int vertices;
  int tetrahedra;
  std::vector<std::string> fields;
};

class ReadDataTest : public DataTest, public ::testing::WithParamInterface<Expected> {};

// Counts from shared/data/README.md.
INSTANTIATE_TEST_SUITE_P(
    SharedData, ReadDataTest,
    ::testing::Values(Expected{"manifoldCheck0_tet.vtu", 29, 24, {"height"}},
                      Expected{"manifoldCheck1_tet.vtu", 24, 24, {"height"}},
                      Expected{"manifoldCheck2_tet.vtu", 20, 24, {"height"}},
                      Expected{"casting_tet.vtu", 14756, 57263, {"eigenfunction4", "height"}},
                      Expected{"fertility_tet.vtu", 14570, 60948, {"eigenfunction4", "height"}},
                      Expected{"isabel02_s2_tet.vtu", 51597, 230640, {"velocityMag"}},
                      Expected{"viscousFingers001_s2_tet.vtu", 32768, 148955, {"density"}}),
    [](const auto& info) {
      std::string name = info.param.file.substr(0, info.param.file.find('.'));
      return name;
    });

TEST_P(ReadDataTest, CountsFieldsAndOrientation) {
  const Expected& expected = GetParam();
  absl::StatusOr<Mesh> mesh = ReadMesh(DataFile(expected.file));
  ASSERT_TRUE(mesh.ok()) << mesh.status();
  EXPECT_EQ(mesh->num_vertices(), expected.vertices);
  EXPECT_EQ(mesh->num_tetrahedra(), expected.tetrahedra);
  EXPECT_EQ(FieldNames(*mesh), expected.fields);
  for (const PointField& field : mesh->point_fields) EXPECT_FALSE(field.is_integer) << field.name;
  // The README promises VTK's positive orientation; this also pins down the sign convention the
  // samples test relies on.
  for (size_t t = 0; t < static_cast<size_t>(mesh->num_tetrahedra()); ++t) {
    ASSERT_GT(SignedVolume6(*mesh, t), 0) << "tetrahedron " << t;
  }
}

TEST_F(DataTest, ReadsEveryVtuButTheTriangleMesh) {
  int read = 0;
  for (const auto& entry : std::filesystem::directory_iterator(DataDir())) {
    if (entry.path().extension() != ".vtu") continue;
    absl::StatusOr<Mesh> mesh = ReadMesh(entry.path().string());
    if (entry.path().filename() == "happi_tas_tri.vtu") {
      EXPECT_FALSE(mesh.ok());
    } else {
      EXPECT_TRUE(mesh.ok()) << mesh.status();
      ++read;
    }
  }
  EXPECT_GE(read, 7);
}

TEST_F(DataTest, FieldValuesMatchTheReadme) {
  absl::StatusOr<Mesh> mesh = ReadMesh(DataFile("fertility_tet.vtu"));
  ASSERT_TRUE(mesh.ok()) << mesh.status();
  // height is the z coordinate.
  const PointField* height = mesh->FindField("height");
  ASSERT_NE(height, nullptr);
  for (int v = 0; v < mesh->num_vertices(); ++v) {
    ASSERT_EQ(height->values[v], mesh->points[3 * v + 2]) << v;
  }
}

TEST_F(DataTest, RefusesTriangleMesh) {
  const std::string path = DataFile("happi_tas_tri.vtu");
  absl::StatusOr<Mesh> mesh = ReadMesh(path);
  ASSERT_FALSE(mesh.ok());
  EXPECT_EQ(mesh.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(mesh.status().message(), HasSubstr("only tetrahedral meshes are served"));
  EXPECT_THAT(mesh.status().message(), HasSubstr("36290 triangle"));
  EXPECT_THAT(mesh.status().message(), HasSubstr(path));
}

TEST_F(DataTest, TetrahedralizesImageDataLikeParaView) {
  absl::StatusOr<Mesh> mesh = ReadMesh(DataFile("isabel_02.vti"));
  ASSERT_TRUE(mesh.ok()) << mesh.status();
  EXPECT_EQ(mesh->num_vertices(), 125 * 125 * 25);
  // vtkDataSetTriangleFilter splits each voxel into 5 tetrahedra.
  EXPECT_EQ(mesh->num_tetrahedra(), 124 * 124 * 24 * 5);
  EXPECT_THAT(FieldNames(*mesh), ElementsAre("velocityMag"));
  // Point ids are the image's: x fastest.
  EXPECT_LT(mesh->points[0], mesh->points[3]);
  EXPECT_EQ(mesh->points[1], mesh->points[4]);
}

TEST_F(DataTest, TetrahedralizesFloatImage) {
  absl::StatusOr<Mesh> mesh = ReadMesh(DataFile("001_density_001_064_2.0.vti"));
  ASSERT_TRUE(mesh.ok()) << mesh.status();
  EXPECT_EQ(mesh->num_vertices(), 64 * 64 * 64);
  EXPECT_EQ(mesh->num_tetrahedra(), 63 * 63 * 63 * 5);
  EXPECT_THAT(FieldNames(*mesh), ElementsAre("ImageFile"));
}

TEST_F(DataTest, ReportsReadingAndStopsWhenCancelled) {
  for (const char* file : {"isabel02_s2_tet.vtu", "isabel_02.vti"}) {
    std::vector<double> fractions;
    const Progress watching({.report = [&](std::string_view phase, double f) {
      EXPECT_EQ(phase, "read");
      fractions.push_back(f);
    }});
    ASSERT_TRUE(ReadMesh(DataFile(file), {}, watching).ok()) << file;
    ASSERT_GE(fractions.size(), 2u) << file;
    EXPECT_EQ(fractions.back(), 1) << file;
    EXPECT_TRUE(std::is_sorted(fractions.begin(), fractions.end()))
        << file << ": " << ::testing::PrintToString(fractions);

    // Cancelled at the reader's first report: VTK aborts the read and nothing is returned.
    std::atomic<bool> cancel{false};
    int reports = 0;
    const Progress cancelling({.cancel = &cancel, .report = [&](std::string_view, double) {
                                 ++reports;
                                 cancel = true;
                               }});
    absl::StatusOr<Mesh> stopped = ReadMesh(DataFile(file), {}, cancelling);
    EXPECT_EQ(stopped.status().code(), absl::StatusCode::kCancelled) << file;
    EXPECT_LT(reports, int(fractions.size())) << file;
  }
}

// Found by fuzz/mesh_file_fuzzer: a compressed block header promising an absurd block count
// made VTK's parser throw std::length_error, which ended the process.
TEST(ReadMeshTest, ACorruptCompressionHeaderIsAnErrorNotACrash) {
  const std::string path =
      std::string(ACTOPO_SOURCE_DIR) + "/server/io/testdata/compressed_header_overflow.vtu";
  absl::StatusOr<Mesh> mesh = ReadMesh(path);
  ASSERT_FALSE(mesh.ok());
  EXPECT_THAT(mesh.status().code(), ::testing::AnyOf(absl::StatusCode::kInvalidArgument,
                                                     absl::StatusCode::kResourceExhausted));
  EXPECT_THAT(mesh.status().message(), HasSubstr("compressed_header_overflow.vtu"));
}

TEST_F(DataTest, RefusesTruncatedFile) {
  const std::filesystem::path dir = MakeTempDir("truncated");
  std::ifstream in(DataFile("fertility_tet.vtu"), std::ios::binary);
  std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const std::string path = (dir / "fertility_half.vtu").string();
  WriteText(path, bytes.substr(0, bytes.size() / 2));
  absl::StatusOr<Mesh> mesh = ReadMesh(path);
  ASSERT_FALSE(mesh.ok());
  EXPECT_EQ(mesh.status().code(), absl::StatusCode::kInvalidArgument) << mesh.status();
  EXPECT_THAT(mesh.status().message(), HasSubstr(path));
}

TEST(ReadMeshTest, MissingFileIsNotFound) {
  const std::string path = "/nonexistent/dir/mesh.vtu";
  absl::StatusOr<Mesh> mesh = ReadMesh(path);
  EXPECT_EQ(mesh.status().code(), absl::StatusCode::kNotFound);
  EXPECT_THAT(mesh.status().message(), HasSubstr(path));
}

TEST(ReadMeshTest, UnsupportedExtension) {
  absl::StatusOr<Mesh> mesh = ReadMesh("/tmp/mesh.obj");
  EXPECT_EQ(mesh.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(mesh.status().message(), HasSubstr("/tmp/mesh.obj"));
  EXPECT_THAT(mesh.status().message(), HasSubstr("'.obj'"));
  EXPECT_THAT(mesh.status().message(), HasSubstr(".vtu"));
  EXPECT_THAT(mesh.status().message(), HasSubstr(".vti"));

  mesh = ReadMesh("/tmp/mesh");
  EXPECT_EQ(mesh.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(mesh.status().message(), HasSubstr("no file extension"));
}

TEST(ReadMeshTest, DirectoryIsRefused) {
  const std::filesystem::path dir = MakeTempDir("directory") / "looks_like.vtu";
  std::filesystem::create_directory(dir);
  absl::StatusOr<Mesh> mesh = ReadMesh(dir.string());
  EXPECT_EQ(mesh.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(mesh.status().message(), HasSubstr("directory"));
}

TEST(ReadMeshTest, GarbageIsInvalidArgumentNamingThePath) {
  const std::filesystem::path dir = MakeTempDir("garbage");
  for (const std::string name : {"garbage.vtu", "garbage.vti", "garbage.vtk", "empty.vtu"}) {
    const std::string path = (dir / name).string();
    WriteText(path, name == "empty.vtu" ? "" : "this is not a VTK file\n\x01\x02\x03");
    absl::StatusOr<Mesh> mesh = ReadMesh(path);
    ASSERT_FALSE(mesh.ok()) << name;
    EXPECT_EQ(mesh.status().code(), absl::StatusCode::kInvalidArgument) << mesh.status();
    EXPECT_THAT(mesh.status().message(), HasSubstr(path));
  }
}

constexpr char kLegacyTwoTetrahedra[] = R"(# vtk DataFile Version 3.0
two tetrahedra
ASCII
DATASET UNSTRUCTURED_GRID
POINTS 5 double
0 0 0
1 0 0
0 1 0
0 0 1
1 1 1
CELLS 2 10
4 0 1 2 3
4 4 3 2 1
CELL_TYPES 2
10
10
POINT_DATA 5
SCALARS temperature double 1
LOOKUP_TABLE default
0.5 1.5 2.5 3.5 4.5
SCALARS label int 1
LOOKUP_TABLE default
7 8 9 10 11
VECTORS velocity double
1 0 0 0 1 0 0 0 1 1 1 1 0 0 0
)";

TEST(ReadMeshTest, LegacyUnstructuredGrid) {
  const std::string path = (MakeTempDir("legacy") / "two.vtk").string();
  WriteText(path, kLegacyTwoTetrahedra);
  absl::StatusOr<Mesh> mesh = ReadMesh(path);
  ASSERT_TRUE(mesh.ok()) << mesh.status();
  EXPECT_THAT(mesh->points, ElementsAre(0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1, 1, 1, 1));
  EXPECT_THAT(mesh->tetrahedra, ElementsAre(0, 1, 2, 3, 4, 3, 2, 1));  // vertex order kept
  // Both SCALARS sections (the legacy reader keeps only the first by default); the vector skipped.
  ASSERT_THAT(FieldNames(*mesh), ElementsAre("temperature", "label"));
  EXPECT_THAT(mesh->point_fields[0].values, ElementsAre(0.5, 1.5, 2.5, 3.5, 4.5));
  EXPECT_FALSE(mesh->point_fields[0].is_integer);
  EXPECT_THAT(mesh->point_fields[1].values, ElementsAre(7, 8, 9, 10, 11));
  EXPECT_TRUE(mesh->point_fields[1].is_integer);
}

TEST(ReadMeshTest, LegacyPolyDataIsRefused) {
  const std::string path = (MakeTempDir("legacy_poly") / "poly.vtk").string();
  WriteText(path, R"(# vtk DataFile Version 3.0
a triangle
ASCII
DATASET POLYDATA
POINTS 3 float
0 0 0 1 0 0 0 1 0
POLYGONS 1 4
3 0 1 2
)");
  absl::StatusOr<Mesh> mesh = ReadMesh(path);
  EXPECT_EQ(mesh.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(mesh.status().message(), HasSubstr("poly data, not an unstructured grid"));
  EXPECT_THAT(mesh.status().message(), HasSubstr(path));
}

TEST(ReadMeshTest, LegacyHexahedronIsRefusedByType) {
  const std::string path = (MakeTempDir("legacy_hex") / "hex.vtk").string();
  WriteText(path, R"(# vtk DataFile Version 3.0
a cube
ASCII
DATASET UNSTRUCTURED_GRID
POINTS 8 float
0 0 0 1 0 0 1 1 0 0 1 0 0 0 1 1 0 1 1 1 1 0 1 1
CELLS 1 9
8 0 1 2 3 4 5 6 7
CELL_TYPES 1
12
)");
  absl::StatusOr<Mesh> mesh = ReadMesh(path);
  EXPECT_EQ(mesh.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(mesh.status().message(), HasSubstr("only tetrahedral meshes are served"));
  EXPECT_THAT(mesh.status().message(), HasSubstr("1 hexahedron (VTK type 12)"));
}

TEST(ReadMeshTest, TetrahedronWithWrongPointCountIsRefused) {
  const std::string path = (MakeTempDir("legacy_short") / "short.vtk").string();
  WriteText(path, R"(# vtk DataFile Version 3.0
a tetrahedron with 3 points
ASCII
DATASET UNSTRUCTURED_GRID
POINTS 4 float
0 0 0 1 0 0 0 1 0 0 0 1
CELLS 2 9
4 0 1 2 3
3 0 1 2
CELL_TYPES 2
10
10
)");
  absl::StatusOr<Mesh> mesh = ReadMesh(path);
  EXPECT_EQ(mesh.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(mesh.status().message(), HasSubstr("tetrahedron 1 has 3 points"));
}

TEST(ReadMeshTest, EmptyGridIsRefused) {
  const std::string path = (MakeTempDir("legacy_empty") / "empty.vtk").string();
  WriteText(path, R"(# vtk DataFile Version 3.0
nothing
ASCII
DATASET UNSTRUCTURED_GRID
POINTS 0 float
)");
  absl::StatusOr<Mesh> mesh = ReadMesh(path);
  EXPECT_EQ(mesh.status().code(), absl::StatusCode::kInvalidArgument) << mesh.status();
}

}  // namespace
}  // namespace actopo::io
