// Meshes downloaded (DownloadMesh): an upload comes back as sent, tetrahedra in their given
// vertex order, added fields with their dtypes and times, and uploads again as itself; a file's
// integer and float32 fields keep their dtypes; progress over the chunks of a real mesh; every
// rejection with its code and message; a throwing callback ends the call.
#include <unistd.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <stdexcept>

#include "tests/testing/fixture.h"
#include "tests/testing/lattice.h"

namespace actopo::client::testing {
namespace {

using absl::StatusCode;

std::vector<std::string> Names(const MeshArrays& mesh) {
  std::vector<std::string> names;
  for (const MeshField& f : mesh.fields) names.push_back(f.name);
  return names;
}

TEST_F(ServerTest, AnUploadComesBackAsSentAndUploadsAgainAsItself) {
  const Lattice lattice(10);
  // Each tetrahedron's vertices in an order of its own: the download keeps it.
  std::vector<int64_t> tets = lattice.tetrahedra;
  for (size_t t = 0; t < tets.size() / 4; ++t) {
    std::rotate(tets.begin() + 4 * t, tets.begin() + 4 * t + t % 4, tets.begin() + 4 * t + 4);
  }
  absl::StatusOr<MeshInfo> uploaded =
      client().UploadMesh(lattice.points, tets, {{"height", lattice.height}}, {.name = "cube"});
  ASSERT_OK(uploaded);
  meshes_.push_back(uploaded->mesh_id);
  std::vector<float> narrow;
  std::vector<double> wide;
  for (double h : lattice.height) {
    narrow.push_back(float(h / 3));
    wide.push_back(h * h);
  }
  ASSERT_OK(client().AddFields(
      uploaded->mesh_id,
      {{.name = "narrow", .values = narrow, .time = 0.5}, {.name = "wide", .values = wide}}));

  absl::StatusOr<MeshArrays> mesh =
      client().DownloadMesh(uploaded->mesh_id, {}, {.all_fields = true});
  ASSERT_OK(mesh);
  EXPECT_EQ(mesh->name, "cube");
  EXPECT_EQ(mesh->vertices(), lattice.vertices());
  EXPECT_EQ(mesh->points, lattice.points);
  EXPECT_EQ(mesh->tetrahedra, tets);
  ASSERT_EQ(Names(*mesh), (std::vector<std::string>{"height", "narrow", "wide"}));
  EXPECT_EQ(mesh->fields[0].dtype, DataType::kFloat64);
  EXPECT_EQ(mesh->fields[0].values, lattice.height);
  EXPECT_EQ(mesh->fields[0].time, std::nullopt);
  const MeshField* narrow_field = mesh->Field("narrow");
  ASSERT_NE(narrow_field, nullptr);
  EXPECT_EQ(narrow_field->dtype, DataType::kFloat32);
  EXPECT_EQ(narrow_field->values, std::vector<double>(narrow.begin(), narrow.end()));
  EXPECT_EQ(narrow_field->time, 0.5);
  EXPECT_EQ(mesh->Field("wide")->values, wide);
  EXPECT_EQ(mesh->Field("nope"), nullptr);

  absl::StatusOr<MeshArrays> picked = client().DownloadMesh(uploaded->mesh_id, {"wide", "height"});
  ASSERT_OK(picked);
  EXPECT_EQ(Names(*picked), (std::vector<std::string>{"wide", "height"}));
  absl::StatusOr<MeshArrays> bare = client().DownloadMesh(uploaded->mesh_id);
  ASSERT_OK(bare);
  EXPECT_TRUE(bare->fields.empty());
  EXPECT_EQ(bare->tetrahedra, tets);

  absl::StatusOr<MeshInfo> again = client().UploadMesh(
      mesh->points, mesh->tetrahedra, {{"height", mesh->fields[0].values}}, {.name = mesh->name});
  ASSERT_OK(again);
  meshes_.push_back(again->mesh_id);
  absl::StatusOr<MeshArrays> round = client().DownloadMesh(again->mesh_id, {"height"});
  ASSERT_OK(round);
  EXPECT_EQ(round->points, lattice.points);
  EXPECT_EQ(round->tetrahedra, tets);
  EXPECT_EQ(round->fields[0].values, lattice.height);
}

// A file written here, with a field of each dtype the server keeps, loaded by a server of its
// own on that folder.
TEST_F(ServerTest, AFilesFieldsKeepTheirDtypes) {
  const std::filesystem::path dir = std::filesystem::temp_directory_path() /
                                    ("actopo-client-download-" + std::to_string(getpid()));
  std::filesystem::create_directories(dir);
  {
    std::ofstream out(dir / "five.vtu");
    out << R"(<?xml version="1.0"?>
<VTKFile type="UnstructuredGrid" version="0.1" byte_order="LittleEndian">
<UnstructuredGrid><Piece NumberOfPoints="5" NumberOfCells="2">
<PointData>
<DataArray type="Int32" Name="label" format="ascii">7 -1 3 0 2</DataArray>
<DataArray type="Int64" Name="big" format="ascii">1099511627779 0 -5 4 9</DataArray>
<DataArray type="Float32" Name="narrow" format="ascii">0.5 0.25 1.5 -2 3.125</DataArray>
<DataArray type="Float64" Name="wide" format="ascii">0.1 0.2 0.3 0.4 0.5</DataArray>
</PointData>
<Points><DataArray type="Float64" NumberOfComponents="3" format="ascii">
0 0 0  1 0 0  0 1 0  0 0 1  1 1 1</DataArray></Points>
<Cells>
<DataArray type="Int64" Name="connectivity" format="ascii">3 1 0 2  2 4 1 3</DataArray>
<DataArray type="Int64" Name="offsets" format="ascii">4 8</DataArray>
<DataArray type="UInt8" Name="types" format="ascii">10 10</DataArray>
</Cells>
</Piece></UnstructuredGrid></VTKFile>
)";
  }
  auto server = ServerProcess::Start(ServerBinary(), dir.string());
  ASSERT_OK(server);
  auto connected = Client::Connect((*server)->target());
  ASSERT_OK(connected);
  Client& c = **connected;
  absl::StatusOr<MeshInfo> loaded = c.LoadMesh("five.vtu");
  ASSERT_OK(loaded);
  absl::StatusOr<MeshArrays> mesh = c.DownloadMesh(loaded->mesh_id, {}, {.all_fields = true});
  std::filesystem::remove_all(dir);
  ASSERT_OK(mesh);
  EXPECT_EQ(mesh->name, "five.vtu");
  EXPECT_EQ(mesh->points, (std::vector<double>{0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1, 1, 1, 1}));
  EXPECT_EQ(mesh->tetrahedra, (std::vector<int64_t>{3, 1, 0, 2, 2, 4, 1, 3}));
  ASSERT_EQ(Names(*mesh), (std::vector<std::string>{"label", "big", "narrow", "wide"}));
  EXPECT_EQ(mesh->fields[0].dtype, DataType::kInt32);
  EXPECT_EQ(mesh->fields[0].values, (std::vector<double>{7, -1, 3, 0, 2}));
  EXPECT_EQ(mesh->fields[1].dtype, DataType::kInt64);
  EXPECT_EQ(mesh->fields[1].values, (std::vector<double>{1099511627779.0, 0, -5, 4, 9}));
  EXPECT_EQ(mesh->fields[2].dtype, DataType::kFloat32);
  EXPECT_EQ(mesh->fields[2].values, (std::vector<double>{0.5, 0.25, 1.5, -2, 3.125}));
  EXPECT_EQ(mesh->fields[3].dtype, DataType::kFloat64);
  EXPECT_EQ(mesh->fields[3].values, (std::vector<double>{0.1, 0.2, 0.3, 0.4, 0.5}));
}

// fertility_tet.vtu with its two fields is 1.6 MB on the wire, in several chunks (of at most
// about 1 MiB, one array's values each), each reported; the fields are those GetMesh describes.
TEST_F(ServerTest, ARealMeshComesInChunksWithProgress) {
  const std::string id = Fertility();
  absl::StatusOr<MeshInfo> info = client().GetMesh(id);
  ASSERT_OK(info);
  std::vector<double> progress;
  absl::StatusOr<MeshArrays> mesh = client().DownloadMesh(
      id, {}, {.all_fields = true, .progress = [&](double f) { progress.push_back(f); }});
  ASSERT_OK(mesh);
  ASSERT_GE(progress.size(), 2u);
  EXPECT_TRUE(std::is_sorted(progress.begin(), progress.end()));
  EXPECT_EQ(progress.back(), 1.0);
  EXPECT_EQ(mesh->vertices(), info->vertices);
  EXPECT_EQ(int64_t(mesh->tetrahedra.size()), 4 * info->tetrahedra);
  EXPECT_EQ(*std::max_element(mesh->tetrahedra.begin(), mesh->tetrahedra.end()),
            info->vertices - 1);
  ASSERT_EQ(mesh->fields.size(), info->fields.size());
  for (size_t i = 0; i < info->fields.size(); ++i) {
    const FieldInfo& described = info->fields[i];
    const MeshField& field = mesh->fields[i];
    EXPECT_EQ(field.name, described.name);
    EXPECT_EQ(field.dtype, described.dtype);
    EXPECT_EQ(*std::min_element(field.values.begin(), field.values.end()), described.min);
    EXPECT_EQ(*std::max_element(field.values.begin(), field.values.end()), described.max);
  }
}

TEST_F(ServerTest, DownloadRejectionsNameWhatWasWrong) {
  const std::string mesh = LoadSample("jittered:4");
  EXPECT_TRUE(
      HasError(client().DownloadMesh("nope"), StatusCode::kNotFound, "mesh_id: no mesh 'nope'"));
  EXPECT_TRUE(HasError(client().DownloadMesh(mesh, {"height", "x"}), StatusCode::kNotFound,
                       "fields[1]: point field 'x' not found; point fields: 'scalar', 'height'"));
  EXPECT_TRUE(HasError(client().DownloadMesh(mesh, {"height", "height"}),
                       StatusCode::kInvalidArgument, "fields[1]: 'height' is listed twice"));
  EXPECT_TRUE(HasError(client().DownloadMesh(mesh, {"height"}, {.all_fields = true}),
                       StatusCode::kInvalidArgument,
                       "fields, options.all_fields: give the fields or all_fields, not both"));
}

TEST_F(ServerTest, AThrowingProgressCallbackEndsTheDownload) {
  const std::string id = Fertility();
  EXPECT_THROW(client().DownloadMesh(
                   id, {}, {.progress = [](double) { throw std::runtime_error("enough"); }}),
               std::runtime_error);
  EXPECT_OK(client().DownloadMesh(id));  // the client goes on
}

}  // namespace
}  // namespace actopo::client::testing
