#include "server/io/internal/vtk_bridge.h"

#include <vtkBitArray.h>
#include <vtkCellArray.h>
#include <vtkDoubleArray.h>
#include <vtkFloatArray.h>
#include <vtkIdTypeArray.h>
#include <vtkNew.h>
#include <vtkPointData.h>
#include <vtkPoints.h>
#include <vtkShortArray.h>
#include <vtkSmartPointer.h>
#include <vtkUnstructuredGrid.h>
#include <vtkXMLUnstructuredGridReader.h>

#include <string>
#include <vector>

#include "absl/status/status.h"
#include "gmock/gmock.h"
#include "gtest/gtest.h"

namespace actopo::io::internal {
namespace {

using ::testing::ElementsAre;
using ::testing::HasSubstr;

// Two tetrahedra over 5 float points, with cells stored in 32- or 64-bit arrays as VTK allows.
template <typename IdArray>
vtkSmartPointer<vtkUnstructuredGrid> TwoTetrahedra(std::vector<typename IdArray::ValueType> ids) {
  vtkNew<vtkPoints> points;
  points->SetDataTypeToFloat();
  for (int i = 0; i < 5; ++i) points->InsertNextPoint(i, i % 2, i * 0.5);
  vtkNew<IdArray> offsets;
  for (int c = 0; c <= static_cast<int>(ids.size() / 4); ++c) offsets->InsertNextValue(4 * c);
  vtkNew<IdArray> connectivity;
  for (auto id : ids) connectivity->InsertNextValue(id);
  vtkNew<vtkCellArray> cells;
  cells->SetData(offsets, connectivity);
  auto grid = vtkSmartPointer<vtkUnstructuredGrid>::New();
  grid->SetPoints(points);
  grid->SetCells(VTK_TETRA, cells);
  return grid;
}

TEST(UnstructuredGridToMeshTest, ThirtyTwoAndSixtyFourBitCells) {
  vtkSmartPointer<vtkUnstructuredGrid> narrow =
      TwoTetrahedra<vtkCellArray::ArrayType32>({0, 1, 2, 3, 4, 3, 2, 1});
  ASSERT_FALSE(narrow->GetCells()->IsStorage64Bit());
  vtkSmartPointer<vtkUnstructuredGrid> wide =
      TwoTetrahedra<vtkCellArray::ArrayType64>({0, 1, 2, 3, 4, 3, 2, 1});
  ASSERT_TRUE(wide->GetCells()->IsStorage64Bit());
  for (vtkUnstructuredGrid* grid : {narrow.Get(), wide.Get()}) {
    absl::StatusOr<Mesh> mesh = UnstructuredGridToMesh(*grid);
    ASSERT_TRUE(mesh.ok()) << mesh.status();
    EXPECT_THAT(mesh->tetrahedra, ElementsAre(0, 1, 2, 3, 4, 3, 2, 1));
    EXPECT_THAT(mesh->points, ElementsAre(0, 0, 0, 1, 1, 0.5, 2, 0, 1, 3, 1, 1.5, 4, 0, 2));
  }
}

TEST(UnstructuredGridToMeshTest, IdsBeyondInt32AreRefused) {
  vtkSmartPointer<vtkUnstructuredGrid> grid =
      TwoTetrahedra<vtkCellArray::ArrayType64>({0, 1, 2, 3, 4, 3, 2, int64_t{1} << 32});
  absl::StatusOr<Mesh> mesh = UnstructuredGridToMesh(*grid);
  EXPECT_EQ(mesh.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(mesh.status().message(), HasSubstr("tetrahedron 1 has vertex id 4294967296"));
}

TEST(UnstructuredGridToMeshTest, PointArrays) {
  vtkSmartPointer<vtkUnstructuredGrid> grid =
      TwoTetrahedra<vtkCellArray::ArrayType32>({0, 1, 2, 3, 4, 3, 2, 1});
  vtkNew<vtkFloatArray> density;
  density->SetName("density");
  vtkNew<vtkShortArray> label;
  label->SetName("label");
  vtkNew<vtkBitArray> flag;  // outside VTK's array dispatch list: the per-value path
  flag->SetName("flag");
  vtkNew<vtkDoubleArray> velocity;  // 3 components: skipped
  velocity->SetName("velocity");
  velocity->SetNumberOfComponents(3);
  vtkNew<vtkDoubleArray> unnamed;
  for (int i = 0; i < 5; ++i) {
    density->InsertNextValue(0.25f * i);
    label->InsertNextValue(static_cast<short>(-i));
    flag->InsertNextValue(i % 2);
    velocity->InsertNextTuple3(i, i, i);
    unnamed->InsertNextValue(i);
  }
  for (vtkDataArray* array : std::vector<vtkDataArray*>{density, label, flag, velocity, unnamed}) {
    grid->GetPointData()->AddArray(array);
  }
  absl::StatusOr<Mesh> mesh = UnstructuredGridToMesh(*grid);
  ASSERT_TRUE(mesh.ok()) << mesh.status();
  ASSERT_EQ(mesh->point_fields.size(), 4u);
  EXPECT_EQ(mesh->point_fields[0].name, "density");
  EXPECT_FALSE(mesh->point_fields[0].is_integer);
  EXPECT_THAT(mesh->point_fields[0].values, ElementsAre(0, 0.25, 0.5, 0.75, 1));
  EXPECT_EQ(mesh->point_fields[1].name, "label");
  EXPECT_TRUE(mesh->point_fields[1].is_integer);
  EXPECT_THAT(mesh->point_fields[1].values, ElementsAre(0, -1, -2, -3, -4));
  EXPECT_EQ(mesh->point_fields[2].name, "flag");
  EXPECT_TRUE(mesh->point_fields[2].is_integer);
  EXPECT_THAT(mesh->point_fields[2].values, ElementsAre(0, 1, 0, 1, 0));
  EXPECT_EQ(mesh->point_fields[3].name, "array4");
}

TEST(UnstructuredGridToMeshTest, EmptyGridFailsValidation) {
  vtkNew<vtkUnstructuredGrid> grid;
  absl::StatusOr<Mesh> mesh = UnstructuredGridToMesh(*grid);
  EXPECT_EQ(mesh.status().code(), absl::StatusCode::kInvalidArgument);
}

TEST(VtkErrorCollectorTest, CatchesReaderErrorsWithoutVtkPrefixes) {
  vtkNew<vtkXMLUnstructuredGridReader> reader;
  VtkErrorCollector errors(reader);
  reader->SetFileName("/nonexistent/file.vtu");
  reader->Update();
  ASSERT_TRUE(errors.has_error());
  EXPECT_THAT(errors.message(), HasSubstr("/nonexistent/file.vtu"));
  EXPECT_THAT(errors.message(), ::testing::Not(HasSubstr("ERROR: In")));
  EXPECT_THAT(errors.message(), ::testing::Not(HasSubstr("(0x")));
}

}  // namespace
}  // namespace actopo::io::internal
