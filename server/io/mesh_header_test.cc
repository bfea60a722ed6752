// Header counts against what ReadMesh finds in the same files: the shared data (.vtu, .vti), and
// legacy files in ASCII, binary and the version-5 layout written by VTK itself.
#include "server/io/mesh_header.h"

#include <vtkNew.h>
#include <vtkUnstructuredGrid.h>
#include <vtkUnstructuredGridWriter.h>
#include <vtkXMLUnstructuredGridReader.h>

#include <filesystem>
#include <fstream>

#include "gmock/gmock.h"
#include "gtest/gtest.h"
#include "server/core/testing/status.h"
#include "server/io/samples.h"
#include "server/io/test_data.h"
#include "server/io/vtk_reader.h"
#include "server/io/vtk_writer.h"

namespace actopo::io {
namespace {

using testing::DataDir;
using testing::DataTest;
using testing::MakeTempDir;

void ExpectCountsOf(const std::string& path) {
  absl::StatusOr<MeshCounts> counts = ReadMeshCounts(path);
  ASSERT_TRUE(counts.ok()) << counts.status();
  absl::StatusOr<Mesh> mesh = ReadMesh(path);
  ASSERT_TRUE(mesh.ok()) << mesh.status();
  EXPECT_EQ(counts->vertices, mesh->num_vertices()) << path;
  EXPECT_EQ(counts->tetrahedra, mesh->num_tetrahedra()) << path;
}

TEST_F(DataTest, HeaderCountsMatchEveryTetrahedralFile) {
  int checked = 0;
  for (const auto& entry : std::filesystem::directory_iterator(DataDir())) {
    const std::string extension = entry.path().extension().string();
    if ((extension != ".vtu" && extension != ".vti") ||
        entry.path().filename() == "happi_tas_tri.vtu") {
      continue;
    }
    ExpectCountsOf(entry.path().string());
    ++checked;
  }
  EXPECT_GE(checked, 9);
}

TEST_F(DataTest, HeaderCountsPointFields) {
  absl::StatusOr<MeshCounts> counts = ReadMeshCounts(DataFile("fertility_tet.vtu"));
  ASSERT_TRUE(counts.ok()) << counts.status();
  EXPECT_EQ(counts->point_fields, 2);  // eigenfunction4, height
}

// A sample written as a legacy file by VTK's own writer, in each layout it produces.
TEST(MeshHeaderTest, LegacyFilesWrittenByVtk) {
  const std::filesystem::path dir = MakeTempDir("header_legacy");
  const std::string vtu = (dir / "sample.vtu").string();
  ASSERT_TRUE(WriteUnstructuredGrid(vtu, OkValue(MakeSample("jittered:7"))).ok());
  vtkNew<vtkXMLUnstructuredGridReader> reader;
  reader->SetFileName(vtu.c_str());
  reader->Update();
  for (const bool binary : {false, true}) {
    for (const int version : {42, 51}) {
      const std::string path =
          (dir / ("sample_" + std::to_string(binary) + "_" + std::to_string(version) + ".vtk"))
              .string();
      vtkNew<vtkUnstructuredGridWriter> writer;
      writer->SetInputData(reader->GetOutput());
      writer->SetFileName(path.c_str());
      if (binary) writer->SetFileTypeToBinary();
      writer->SetFileVersion(version);
      ASSERT_EQ(writer->Write(), 1);
      SCOPED_TRACE(path);
      ExpectCountsOf(path);
    }
  }
}

TEST(MeshHeaderTest, WhatHasNoCountsIsInvalidArgument) {
  const std::filesystem::path dir = MakeTempDir("header_bad");
  const auto write = [&](const std::string& name, const std::string& text) {
    std::ofstream(dir / name) << text;
    return (dir / name).string();
  };
  EXPECT_EQ(ReadMeshCounts(write("empty.vtu", "")).status().code(),
            absl::StatusCode::kInvalidArgument);
  EXPECT_EQ(
      ReadMeshCounts(write("piece.vtu", "<VTKFile><Piece NumberOfPoints=\"4\">")).status().code(),
      absl::StatusCode::kInvalidArgument);
  EXPECT_EQ(ReadMeshCounts(write("noextent.vti", "<VTKFile><ImageData>")).status().code(),
            absl::StatusCode::kInvalidArgument);
  EXPECT_EQ(ReadMeshCounts(write("nopoints.vtk", "# vtk DataFile Version 3.0\nx\nASCII\n"))
                .status()
                .code(),
            absl::StatusCode::kInvalidArgument);
  EXPECT_EQ(ReadMeshCounts((dir / "missing.vtu").string()).status().code(),
            absl::StatusCode::kNotFound);
  // Huge claims are read as claimed: the budget, not the parser, refuses them.
  absl::StatusOr<MeshCounts> huge = ReadMeshCounts(write(
      "huge.vtu", "<VTKFile><Piece NumberOfPoints=\"9000000000\" NumberOfCells=\"70000000000\">"));
  ASSERT_TRUE(huge.ok()) << huge.status();
  EXPECT_EQ(huge->tetrahedra, 70000000000);
}

// Markup any XML writer may produce: attributes on lines of their own, single quotes, comments.
TEST(MeshHeaderTest, CountsThroughAnyWellFormedMarkup) {
  const std::filesystem::path dir = MakeTempDir("header_markup");
  const auto write = [&](const std::string& name, const std::string& text) {
    std::ofstream(dir / name) << text;
    return (dir / name).string();
  };
  const std::string vtu = write("lines.vtu", R"(<?xml version="1.0"?>
<VTKFile type='UnstructuredGrid'>
  <!-- <Piece NumberOfPoints="1000" NumberOfCells="1000"> -->
  <UnstructuredGrid>
    <Piece
        NumberOfPoints='8'
        NumberOfCells = "5">
      <PointData>
        <DataArray	type="Float64"	Name='f'/>
        <DataArray type="Float64" Name="v" NumberOfComponents='3'/>
        <DataArray type="Int32" Name="id" NumberOfComponents="1">1 2 3</DataArray>
      </PointData>
    </Piece>
    <Piece NumberOfPoints="2" NumberOfCells="1"/>
  </UnstructuredGrid>
</VTKFile>
)");
  absl::StatusOr<MeshCounts> counts = ReadMeshCounts(vtu);
  ASSERT_TRUE(counts.ok()) << counts.status();
  EXPECT_EQ(counts->vertices, 10);
  EXPECT_EQ(counts->tetrahedra, 6);
  EXPECT_EQ(counts->point_fields, 2);  // f and id

  const std::string vti = write("lines.vti",
                                "<VTKFile type='ImageData'>\n"
                                "<ImageData WholeExtent='0 2\n\t0 3  0 4'>\n"
                                "<PointData/><Piece/></ImageData></VTKFile>");
  counts = ReadMeshCounts(vti);
  ASSERT_TRUE(counts.ok()) << counts.status();
  EXPECT_EQ(counts->vertices, 3 * 4 * 5);
  EXPECT_EQ(counts->tetrahedra, 5 * 2 * 3 * 4);
  EXPECT_EQ(counts->point_fields, 0);

  // Markup the reader refuses: no counts, and the reason.
  const absl::StatusOr<MeshCounts> bad =
      ReadMeshCounts(write("bad.vtu", "<VTKFile><Piece NumberOfPoints='1'NumberOfCells='1'>"));
  EXPECT_EQ(bad.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(bad.status().message(),
              ::testing::HasSubstr("no counts in the header: markup it cannot read at byte 9"));
}

}  // namespace
}  // namespace actopo::io
