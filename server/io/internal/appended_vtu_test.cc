#include "server/io/internal/appended_vtu.h"

#include <vtkCellArray.h>
#include <vtkDoubleArray.h>
#include <vtkFloatArray.h>
#include <vtkIntArray.h>
#include <vtkNew.h>
#include <vtkPointData.h>
#include <vtkPoints.h>
#include <vtkUnstructuredGrid.h>
#include <vtkXMLUnstructuredGridWriter.h>

#include <filesystem>
#include <fstream>
#include <string>

#include "absl/strings/str_cat.h"
#include "gtest/gtest.h"
#include "server/core/testing/status.h"
#include "server/io/samples.h"
#include "server/io/test_data.h"
#include "server/io/vtk_reader.h"

namespace actopo::io::internal {
namespace {

using testing::DataDir;
using testing::MakeTempDir;

// Equal as the service needs them: the same points, tetrahedra and fields, bit for bit.
void ExpectSameMesh(const Mesh& a, const Mesh& b, const std::string& what) {
  EXPECT_EQ(a.points, b.points) << what;
  EXPECT_EQ(a.tetrahedra, b.tetrahedra) << what;
  ASSERT_EQ(a.point_fields.size(), b.point_fields.size()) << what;
  for (size_t i = 0; i < a.point_fields.size(); ++i) {
    const PointField &x = a.point_fields[i], &y = b.point_fields[i];
    EXPECT_EQ(x.name, y.name) << what;
    EXPECT_EQ(x.values, y.values) << what << " " << x.name;
    EXPECT_EQ(x.is_integer, y.is_integer) << what << " " << x.name;
    EXPECT_EQ(x.source_bytes, y.source_bytes) << what << " " << x.name;
  }
}

Mesh ReadWithVtk(const std::string& path) {
  absl::StatusOr<Mesh> mesh = ReadMesh(path, {.parallel_vtu = false});
  EXPECT_TRUE(mesh.ok()) << mesh.status();
  return mesh.ok() ? *std::move(mesh) : Mesh{};
}

// Every shared .vtu is in the default layout: the parallel reader reads it, on 1 to 3 threads,
// exactly as VTK does; the triangle mesh it leaves to VTK, which refuses it.
TEST(AppendedVtu, ReadsEverySharedFileAsVtkDoes) {
  int read = 0;
  for (const auto& entry : std::filesystem::directory_iterator(DataDir())) {
    if (entry.path().extension() != ".vtu") continue;
    const std::string path = entry.path().string();
    for (int threads : {1, 2, 3}) {
      absl::StatusOr<std::optional<Mesh>> fast = ReadAppendedVtu(path, threads, {});
      ASSERT_TRUE(fast.ok()) << path << ": " << fast.status();
      if (entry.path().filename() == "happi_tas_tri.vtu") {
        EXPECT_FALSE(fast->has_value()) << "triangles are VTK's to refuse";
        continue;
      }
      ASSERT_TRUE(fast->has_value()) << path << " went to VTK";
      ExpectSameMesh(**fast, ReadWithVtk(path), absl::StrCat(path, ", threads ", threads));
      ++read;
    }
  }
  EXPECT_GE(read, 3 * 7);
}

// A mesh with what files carry: a float field, an integer field and a vector field (skipped).
vtkNew<vtkUnstructuredGrid> Grid(const Mesh& mesh, bool ids32) {
  vtkNew<vtkUnstructuredGrid> grid;
  vtkNew<vtkPoints> points;
  points->SetDataTypeToFloat();
  for (SimplexId v = 0; v < mesh.num_vertices(); ++v) {
    points->InsertNextPoint(mesh.points[3 * v], mesh.points[3 * v + 1], mesh.points[3 * v + 2]);
  }
  grid->SetPoints(points);
  vtkNew<vtkCellArray> cells;
  for (SimplexId t = 0; t < mesh.num_tetrahedra(); ++t) {
    const vtkIdType ids[4] = {mesh.tetrahedra[4 * t], mesh.tetrahedra[4 * t + 1],
                              mesh.tetrahedra[4 * t + 2], mesh.tetrahedra[4 * t + 3]};
    cells->InsertNextCell(4, ids);
  }
  if (ids32) cells->ConvertTo32BitStorage();
  grid->SetCells(VTK_TETRA, cells);
  vtkNew<vtkFloatArray> scalar;
  scalar->SetName("f");
  vtkNew<vtkIntArray> label;
  label->SetName("label");
  vtkNew<vtkDoubleArray> vector;
  vector->SetName("v");
  vector->SetNumberOfComponents(3);
  for (SimplexId v = 0; v < mesh.num_vertices(); ++v) {
    scalar->InsertNextValue(float(mesh.point_fields[0].values[v]));
    label->InsertNextValue(int(v % 7) - 3);
    vector->InsertNextTuple3(v, 2 * v, 3 * v);
  }
  grid->GetPointData()->AddArray(scalar);
  grid->GetPointData()->AddArray(vector);
  grid->GetPointData()->AddArray(label);
  return grid;
}

struct Layout {
  const char* name;
  int mode;  // vtkXMLWriter::Appended, Binary, Ascii
  bool raw;  // appended data not base64-encoded
  bool zlib;
  bool header64;
  bool ids32;
  int block_bytes;
  bool fast;  // the parallel reader takes it
};

// Every layout VTK's writer offers reads as VTK reads it; the raw appended ones in parallel.
TEST(AppendedVtu, EveryLayoutReadsAsVtkDoes) {
  const Mesh mesh = OkValue(MakeSample("jittered:6"));
  const std::filesystem::path dir = MakeTempDir("appended_vtu");
  const Layout layouts[] = {
      {"zlib", vtkXMLWriter::Appended, true, true, true, false, 32768, true},
      {"zlib, small blocks", vtkXMLWriter::Appended, true, true, true, false, 1024, true},
      {"zlib, 32-bit header and ids", vtkXMLWriter::Appended, true, true, false, true, 4096, true},
      {"uncompressed", vtkXMLWriter::Appended, true, false, true, false, 32768, true},
      {"uncompressed, 32-bit", vtkXMLWriter::Appended, true, false, false, true, 32768, true},
      {"base64 appended", vtkXMLWriter::Appended, false, true, true, false, 32768, false},
      {"inline binary", vtkXMLWriter::Binary, false, true, true, false, 32768, false},
      {"ascii", vtkXMLWriter::Ascii, false, false, true, false, 32768, false},
  };
  for (const Layout& layout : layouts) {
    const std::string path = (dir / absl::StrCat(&layout - layouts, ".vtu")).string();
    vtkNew<vtkXMLUnstructuredGridWriter> writer;
    writer->SetInputData(Grid(mesh, layout.ids32));
    writer->SetFileName(path.c_str());
    writer->SetDataMode(layout.mode);
    writer->SetEncodeAppendedData(!layout.raw);
    if (layout.zlib) {
      writer->SetCompressorTypeToZLib();
    } else {
      writer->SetCompressorTypeToNone();
    }
    writer->SetHeaderType(layout.header64 ? vtkXMLWriter::UInt64 : vtkXMLWriter::UInt32);
    writer->SetBlockSize(layout.block_bytes);
    ASSERT_EQ(writer->Write(), 1) << layout.name;

    absl::StatusOr<std::optional<Mesh>> fast = ReadAppendedVtu(path, 2, {});
    ASSERT_TRUE(fast.ok()) << layout.name << ": " << fast.status();
    EXPECT_EQ(fast->has_value(), layout.fast) << layout.name;
    const Mesh reference = ReadWithVtk(path);
    ASSERT_EQ(reference.point_fields.size(), 2u) << layout.name << ": f and label, not v";
    EXPECT_TRUE(reference.point_fields[1].is_integer);
    absl::StatusOr<Mesh> read = ReadMesh(path);
    ASSERT_TRUE(read.ok()) << layout.name << ": " << read.status();
    ExpectSameMesh(*read, reference, layout.name);
  }
}

// Field names that a file holds escaped ("h&amp;t", which VTK's writer leaves to its caller) or
// that XML's parser changes (a tab becomes a space): the file goes to VTK, so the fields are
// named as VTK names them.
TEST(AppendedVtu, NamesVtkWouldReadOtherwiseGoToVtk) {
  const Mesh mesh = OkValue(MakeSample("jittered:4"));
  const std::filesystem::path dir = MakeTempDir("appended_vtu_names");
  for (const std::string name : {"h&amp;t", "tab\there"}) {
    vtkNew<vtkUnstructuredGrid> grid = Grid(mesh, false);
    grid->GetPointData()->GetArray("f")->SetName(name.c_str());
    const std::string path = (dir / "named.vtu").string();
    vtkNew<vtkXMLUnstructuredGridWriter> writer;
    writer->SetInputData(grid);
    writer->SetFileName(path.c_str());
    writer->SetDataModeToAppended();
    ASSERT_EQ(writer->Write(), 1) << name;
    absl::StatusOr<std::optional<Mesh>> fast = ReadAppendedVtu(path, 2, {});
    ASSERT_TRUE(fast.ok()) << name << ": " << fast.status();
    EXPECT_FALSE(fast->has_value()) << name;
    const Mesh reference = ReadWithVtk(path);
    ExpectSameMesh(OkValue(ReadMesh(path)), reference, name);
    EXPECT_EQ(reference.point_fields[0].name, name == "h&amp;t" ? "h&t" : "tab here");
  }
}

std::string Slurp(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

// Damage the parallel reader cannot take goes to VTK, whose error the caller gets, the same as
// without the parallel reader.
TEST(AppendedVtu, DamageGetsVtksError) {
  const std::string original = Slurp(DataDir() + "/fertility_tet.vtu");
  const std::filesystem::path dir = MakeTempDir("appended_vtu_damage");
  const size_t data = original.find('_', original.find("<AppendedData")) + 1;
  ASSERT_GT(data, 0u);
  struct Damage {
    const char* name;
    size_t at;  // from the appended data's start
  };
  // The first array's header: block count, block size, last block's size, then the sizes.
  for (const Damage& damage : {Damage{"a block's bytes", 4000}, Damage{"a block size", 8}}) {
    std::string bytes = original;
    for (size_t i = 0; i < 16; ++i) bytes[data + damage.at + i] ^= 0x5a;
    const std::string path = (dir / "damaged.vtu").string();
    std::ofstream(path, std::ios::binary) << bytes;
    absl::StatusOr<std::optional<Mesh>> fast = ReadAppendedVtu(path, 2, {});
    ASSERT_TRUE(fast.ok()) << damage.name;
    EXPECT_FALSE(fast->has_value()) << damage.name;
    const absl::StatusOr<Mesh> with_vtk = ReadMesh(path, {.parallel_vtu = false});
    const absl::StatusOr<Mesh> read = ReadMesh(path);
    EXPECT_EQ(read.status(), with_vtk.status()) << damage.name;
  }
  // A vertex id beyond the points, uncompressed so the id is written as is.
  const Mesh mesh = OkValue(MakeSample("jittered:3"));
  vtkNew<vtkXMLUnstructuredGridWriter> writer;
  vtkNew<vtkUnstructuredGrid> grid = Grid(mesh, false);
  grid->GetCells()->GetConnectivityArray64()->SetValue(5, mesh.num_vertices());
  const std::string path = (dir / "beyond.vtu").string();
  writer->SetInputData(grid);
  writer->SetFileName(path.c_str());
  writer->SetDataModeToAppended();
  writer->EncodeAppendedDataOff();
  writer->SetCompressorTypeToNone();
  ASSERT_EQ(writer->Write(), 1);
  EXPECT_FALSE(ReadAppendedVtu(path, 2, {})->has_value());
  const absl::StatusOr<Mesh> read = ReadMesh(path);
  EXPECT_FALSE(read.ok());
  EXPECT_EQ(read.status(), ReadMesh(path, {.parallel_vtu = false}).status());
}

}  // namespace
}  // namespace actopo::io::internal
