#include "server/io/vtk_writer.h"

#include <vtkCell.h>
#include <vtkCellArray.h>
#include <vtkCellData.h>
#include <vtkDataArray.h>
#include <vtkNew.h>
#include <vtkPointData.h>
#include <vtkPolyData.h>
#include <vtkType.h>
#include <vtkUnstructuredGrid.h>
#include <vtkXMLPolyDataReader.h>
#include <vtkXMLUnstructuredGridReader.h>

#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "gmock/gmock.h"
#include "gtest/gtest.h"
#include "server/io/samples.h"
#include "server/io/test_data.h"
#include "server/io/vtk_reader.h"

namespace actopo::io {
namespace {

using ::testing::ElementsAre;
using ::testing::HasSubstr;
using testing::MakeTempDir;

std::string ReadText(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

std::vector<double> Values(vtkDataArray* array) {
  std::vector<double> values;
  for (vtkIdType i = 0; i < array->GetNumberOfTuples(); ++i) values.push_back(array->GetTuple1(i));
  return values;
}

Mesh Jittered3() {
  absl::StatusOr<Mesh> mesh = MakeSample("jittered:3");
  EXPECT_TRUE(mesh.ok()) << mesh.status();
  return *std::move(mesh);
}

TEST(WriteUnstructuredGridTest, RoundTripWithExtraArrays) {
  Mesh mesh = Jittered3();
  const size_t n = mesh.num_vertices();
  PointField label{.name = "label", .values = std::vector<double>(n), .is_integer = true};
  for (size_t v = 0; v < n; ++v) label.values[v] = static_cast<double>(v % 5) - 2;
  mesh.point_fields.push_back(label);

  std::vector<NamedArray> extra(4);
  extra[0].name = "Order";
  extra[1].name = "CriticalType";
  extra[2].name = "Persistence";
  extra[3].name = "Ratio";
  std::vector<int32_t> order(n);
  std::vector<int8_t> type(n);
  std::vector<double> persistence(n);
  std::vector<float> ratio(n);
  for (size_t v = 0; v < n; ++v) {
    order[v] = static_cast<int32_t>(n - v) * 1000;
    type[v] = static_cast<int8_t>(v % 6) - 1;
    persistence[v] = 1.0 / (v + 1);
    ratio[v] = 0.1f * v;
  }
  extra[0].values = order;
  extra[1].values = type;
  extra[2].values = persistence;
  extra[3].values = ratio;

  const std::string path = (MakeTempDir("vtu_round_trip") / "mesh.vtu").string();
  ASSERT_TRUE(WriteUnstructuredGrid(path, mesh, extra).ok());
  // Binary appended and zlib-compressed, as the brief for ParaView output asks.
  const std::string text = ReadText(path);
  EXPECT_THAT(text, HasSubstr("compressor=\"vtkZLibDataCompressor\""));
  EXPECT_THAT(text, HasSubstr("<AppendedData encoding=\"raw\">"));

  absl::StatusOr<Mesh> back = ReadMesh(path);
  ASSERT_TRUE(back.ok()) << back.status();
  EXPECT_EQ(back->points, mesh.points);
  EXPECT_EQ(back->tetrahedra, mesh.tetrahedra);
  ASSERT_EQ(back->point_fields.size(), 7u);
  const std::vector<std::pair<std::string, bool>> expected = {
      {"scalar", false},      {"height", false},      {"label", true}, {"Order", true},
      {"CriticalType", true}, {"Persistence", false}, {"Ratio", false}};
  for (size_t i = 0; i < expected.size(); ++i) {
    EXPECT_EQ(back->point_fields[i].name, expected[i].first);
    EXPECT_EQ(back->point_fields[i].is_integer, expected[i].second) << expected[i].first;
  }
  for (size_t i = 0; i < 3; ++i)
    EXPECT_EQ(back->point_fields[i].values, mesh.point_fields[i].values);
  for (size_t v = 0; v < n; ++v) {
    EXPECT_EQ(back->point_fields[3].values[v], order[v]);
    EXPECT_EQ(back->point_fields[4].values[v], type[v]);
    EXPECT_EQ(back->point_fields[5].values[v], persistence[v]);
    EXPECT_EQ(back->point_fields[6].values[v], ratio[v]);
  }
}

TEST(WriteUnstructuredGridTest, WideIntegerFieldFallsBackToDouble) {
  Mesh mesh = Jittered3();
  PointField wide{
      .name = "wide", .values = std::vector<double>(mesh.num_vertices(), 5e9), .is_integer = true};
  mesh.point_fields.push_back(wide);
  const std::string path = (MakeTempDir("vtu_wide") / "mesh.vtu").string();
  ASSERT_TRUE(WriteUnstructuredGrid(path, mesh).ok());
  absl::StatusOr<Mesh> back = ReadMesh(path);
  ASSERT_TRUE(back.ok()) << back.status();
  EXPECT_EQ(back->FindField("wide")->values, wide.values);
}

// A float32 field is written as Float32 (as TTK's outputs keep it), unless a value is no float.
TEST(WriteUnstructuredGridTest, Float32FieldsStayFloat32) {
  Mesh mesh = Jittered3();
  const size_t n = mesh.num_vertices();
  PointField narrow{.name = "narrow", .values = std::vector<double>(n), .source_bytes = 4};
  for (size_t v = 0; v < n; ++v) narrow.values[v] = double(0.1f * float(v));
  PointField changed = narrow;
  changed.name = "changed";
  changed.values[n / 2] = 0.1;  // no float is 0.1
  mesh.point_fields.push_back(narrow);
  mesh.point_fields.push_back(changed);
  const std::string path = (MakeTempDir("vtu_float32") / "mesh.vtu").string();
  ASSERT_TRUE(WriteUnstructuredGrid(path, mesh).ok());
  const std::string text = ReadText(path);
  EXPECT_THAT(text, HasSubstr("type=\"Float32\" Name=\"narrow\""));
  EXPECT_THAT(text, HasSubstr("type=\"Float64\" Name=\"changed\""));
  absl::StatusOr<Mesh> back = ReadMesh(path);
  ASSERT_TRUE(back.ok()) << back.status();
  EXPECT_EQ(back->FindField("narrow")->values, narrow.values);
  EXPECT_EQ(back->FindField("narrow")->source_bytes, 4);
  EXPECT_EQ(back->FindField("changed")->values, changed.values);
  EXPECT_EQ(back->FindField("changed")->source_bytes, 8);
}

TEST(WriteUnstructuredGridTest, RefusesBadArrays) {
  const Mesh mesh = Jittered3();
  const std::string path = (MakeTempDir("vtu_bad") / "mesh.vtu").string();
  std::vector<NamedArray> extra = {{"Short", std::vector<double>(3)}};
  absl::Status status = WriteUnstructuredGrid(path, mesh, extra);
  EXPECT_EQ(status.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(status.message(), HasSubstr("'Short' has 3 values, expected 27"));

  extra = {{"height", std::vector<double>(27)}};
  status = WriteUnstructuredGrid(path, mesh, extra);
  EXPECT_EQ(status.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(status.message(), HasSubstr("'height': the name is used twice"));

  Mesh broken = mesh;
  broken.tetrahedra[0] = 1000;
  EXPECT_EQ(WriteUnstructuredGrid(path, broken).code(), absl::StatusCode::kOutOfRange);
}

TEST(WriteUnstructuredGridTest, UnwritablePaths) {
  const Mesh mesh = Jittered3();
  absl::Status status = WriteUnstructuredGrid("/nonexistent/dir/mesh.vtu", mesh);
  EXPECT_EQ(status.code(), absl::StatusCode::kNotFound);
  EXPECT_THAT(status.message(), HasSubstr("/nonexistent/dir/mesh.vtu"));

  const std::filesystem::path dir = MakeTempDir("vtu_unwritable");
  status = WriteUnstructuredGrid((dir / "mesh.vtp").string(), mesh);
  EXPECT_EQ(status.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(status.message(), HasSubstr("must end in .vtu"));

  std::filesystem::create_directory(dir / "taken.vtu");
  status = WriteUnstructuredGrid((dir / "taken.vtu").string(), mesh);
  EXPECT_EQ(status.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(status.message(), HasSubstr("taken.vtu"));

  // The directory exists but nothing can be created in it: VTK's own open fails.
  status = WriteUnstructuredGrid("/proc/self/mesh.vtu", mesh);
  EXPECT_FALSE(status.ok());
  EXPECT_THAT(status.message(), HasSubstr("/proc/self/mesh.vtu"));
}

vtkSmartPointer<vtkPolyData> ReadPolyData(const std::string& path) {
  vtkNew<vtkXMLPolyDataReader> reader;
  reader->SetFileName(path.c_str());
  reader->Update();
  return reader->GetOutput();
}

TEST(WritePolyDataTest, LinesWithPointAndCellArrays) {
  PolyData poly;
  poly.points = {0, 0, 0, 1, 0, 0, 1, 1, 0, 1, 1, 1};
  poly.line_offsets = {0, 3, 5};
  poly.line_connectivity = {0, 1, 2, 2, 3};
  poly.point_arrays.push_back({"CriticalType", std::vector<int8_t>{0, -1, 1, 3}});
  poly.point_arrays.push_back({"Scalar", std::vector<double>{0.5, 1.5, 2.5, 3.5}});
  poly.cell_arrays.push_back({"SeparatrixId", std::vector<int32_t>{10, 11}});
  poly.cell_arrays.push_back({"SeparatrixFunctionMaximum", std::vector<float>{2.5f, 3.5f}});
  const std::string path = (MakeTempDir("vtp_lines") / "separatrices.vtp").string();
  ASSERT_TRUE(WritePolyData(path, poly).ok());

  vtkSmartPointer<vtkPolyData> back = ReadPolyData(path);
  ASSERT_EQ(back->GetNumberOfPoints(), 4);
  EXPECT_EQ(back->GetNumberOfLines(), 2);
  EXPECT_EQ(back->GetNumberOfVerts(), 0);
  vtkIdType size = 0;
  const vtkIdType* ids = nullptr;
  back->GetLines()->GetCellAtId(1, size, ids);
  EXPECT_THAT(std::vector<vtkIdType>(ids, ids + size), ElementsAre(2, 3));

  vtkDataArray* type = back->GetPointData()->GetArray("CriticalType");
  ASSERT_NE(type, nullptr);
  EXPECT_EQ(type->GetDataType(), VTK_SIGNED_CHAR);
  EXPECT_THAT(Values(type), ElementsAre(0, -1, 1, 3));
  vtkDataArray* scalar = back->GetPointData()->GetArray("Scalar");
  ASSERT_NE(scalar, nullptr);
  EXPECT_EQ(scalar->GetDataType(), VTK_DOUBLE);
  EXPECT_THAT(Values(scalar), ElementsAre(0.5, 1.5, 2.5, 3.5));
  vtkDataArray* id = back->GetCellData()->GetArray("SeparatrixId");
  ASSERT_NE(id, nullptr);
  EXPECT_EQ(id->GetDataType(), VTK_INT);
  EXPECT_THAT(Values(id), ElementsAre(10, 11));
  vtkDataArray* maximum = back->GetCellData()->GetArray("SeparatrixFunctionMaximum");
  ASSERT_NE(maximum, nullptr);
  EXPECT_EQ(maximum->GetDataType(), VTK_FLOAT);
  EXPECT_THAT(Values(maximum), ElementsAre(2.5, 3.5));
}

TEST(WritePolyDataTest, PointsOnlyBecomeVertexCells) {
  PolyData poly;
  poly.points = {0, 0, 0, 1, 0, 0, 0, 1, 0};
  poly.point_arrays.push_back({"CriticalType", std::vector<int8_t>{0, 1, 3}});
  poly.cell_arrays.push_back({"CellId", std::vector<int32_t>{5, 6, 7}});
  const std::string path = (MakeTempDir("vtp_points") / "critical_points.vtp").string();
  ASSERT_TRUE(WritePolyData(path, poly).ok());

  vtkSmartPointer<vtkPolyData> back = ReadPolyData(path);
  EXPECT_EQ(back->GetNumberOfPoints(), 3);
  EXPECT_EQ(back->GetNumberOfVerts(), 3);
  EXPECT_EQ(back->GetNumberOfLines(), 0);
  EXPECT_THAT(Values(back->GetCellData()->GetArray("CellId")), ElementsAre(5, 6, 7));
}

TEST(WritePolyDataTest, EmptyPolyData) {
  const std::string path = (MakeTempDir("vtp_empty") / "nothing.vtp").string();
  ASSERT_TRUE(WritePolyData(path, PolyData{}).ok());
  EXPECT_EQ(ReadPolyData(path)->GetNumberOfPoints(), 0);
}

// TTK's persistence diagrams: line cells in an unstructured grid, a 3-component point array.
TEST(WritePolyDataTest, LinesAsAnUnstructuredGridWithTuples) {
  PolyData poly;
  poly.points = {0, 0, 0, 0, 1, 0, 1, 1, 0, 1, 3, 0};
  poly.line_offsets = {0, 2, 4};
  poly.line_connectivity = {0, 1, 2, 3};
  poly.point_arrays.push_back(
      {"Coordinates", std::vector<float>{1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12}, 3});
  poly.cell_arrays.push_back({"PairIdentifier", std::vector<int32_t>{0, 1}});
  const std::string path = (MakeTempDir("vtu_lines") / "diagram.vtu").string();
  ASSERT_TRUE(WritePolyData(path, poly).ok());

  vtkNew<vtkXMLUnstructuredGridReader> reader;
  reader->SetFileName(path.c_str());
  reader->Update();
  vtkUnstructuredGrid* back = reader->GetOutput();
  ASSERT_EQ(back->GetNumberOfPoints(), 4);
  ASSERT_EQ(back->GetNumberOfCells(), 2);
  EXPECT_EQ(back->GetCellType(1), VTK_LINE);
  EXPECT_EQ(back->GetCell(1)->GetPointId(1), 3);
  vtkDataArray* coordinates = back->GetPointData()->GetArray("Coordinates");
  ASSERT_NE(coordinates, nullptr);
  EXPECT_EQ(coordinates->GetDataType(), VTK_FLOAT);
  EXPECT_EQ(coordinates->GetNumberOfComponents(), 3);
  EXPECT_EQ(coordinates->GetComponent(2, 1), 8);
  EXPECT_THAT(Values(back->GetCellData()->GetArray("PairIdentifier")), ElementsAre(0, 1));

  poly.point_arrays[0].values = std::vector<float>(11, 0.0f);
  const absl::Status status = WritePolyData(path, poly);
  EXPECT_EQ(status.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(status.message(), HasSubstr("'Coordinates' has 11 values in tuples of 3"));
  EXPECT_THAT(WritePolyData(path + ".vtk", poly).message(), HasSubstr("must end in .vtp or .vtu"));
}

TEST(WritePolyDataTest, RefusesMalformedInput) {
  const std::string path = (MakeTempDir("vtp_bad") / "bad.vtp").string();
  PolyData poly;
  poly.points = {0, 0, 0, 1, 0, 0};
  poly.line_offsets = {0, 2};
  poly.line_connectivity = {0, 2};
  absl::Status status = WritePolyData(path, poly);
  EXPECT_EQ(status.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(status.message(), HasSubstr("line_connectivity: entry 1 is 2"));

  poly.line_connectivity = {0, 1};
  poly.cell_arrays.push_back({"SeparatrixId", std::vector<int32_t>{1, 2}});
  status = WritePolyData(path, poly);
  EXPECT_EQ(status.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(status.message(), HasSubstr("line array 'SeparatrixId' has 2 values, expected 1"));

  poly.cell_arrays.clear();
  poly.point_arrays.push_back({"CriticalType", std::vector<int8_t>{1}});
  status = WritePolyData(path, poly);
  EXPECT_THAT(status.message(), HasSubstr("point array 'CriticalType' has 1 values, expected 2"));

  poly.point_arrays.clear();
  poly.line_offsets = {0, 1, 2};
  status = WritePolyData(path, poly);
  EXPECT_THAT(status.message(), HasSubstr("line 0 has 1 points"));

  poly.points.push_back(1);
  status = WritePolyData(path, poly);
  EXPECT_THAT(status.message(), HasSubstr("not a multiple of 3"));
}

}  // namespace
}  // namespace actopo::io
