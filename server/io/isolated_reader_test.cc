// Reading in a child process: the same mesh as reading in process, and every way the child can
// fail (a crash inside VTK, a cancel, a refused size, a missing reader) is an error here.
#include "server/io/isolated_reader.h"

#include <atomic>
#include <filesystem>
#include <fstream>
#include <string>

#include "absl/status/status.h"
#include "gmock/gmock.h"
#include "gtest/gtest.h"
#include "server/io/test_data.h"
#include "server/io/vtk_reader.h"

namespace actopo::io {
namespace {

using ::testing::AllOf;
using testing::DataTest;
using ::testing::HasSubstr;
using testing::MakeTempDir;

IsolatedReadOptions Isolated(int64_t memory_limit_bytes = int64_t(256) << 20) {
  return {.reader = ACTOPO_READER_BIN, .memory_limit_bytes = memory_limit_bytes};
}

TEST_F(DataTest, IsolatedReadGivesTheSameMeshAsReadingInProcess) {
  for (const char* file : {"fertility_tet.vtu", "isabel_02.vti", "manifoldCheck0_tet.vtu"}) {
    absl::StatusOr<Mesh> here = ReadMesh(DataFile(file));
    ASSERT_TRUE(here.ok()) << here.status();
    int reports = 0;
    double last = -1;
    const Progress watching({.report = [&](std::string_view phase, double fraction) {
      EXPECT_EQ(phase, "read");
      ++reports;
      last = fraction;
    }});
    absl::StatusOr<Mesh> there = ReadMeshIsolated(DataFile(file), Isolated(), watching);
    ASSERT_TRUE(there.ok()) << there.status();
    EXPECT_EQ(there->points, here->points) << file;
    EXPECT_EQ(there->tetrahedra, here->tetrahedra) << file;
    ASSERT_EQ(there->point_fields.size(), here->point_fields.size()) << file;
    for (size_t i = 0; i < here->point_fields.size(); ++i) {
      const PointField &a = there->point_fields[i], &b = here->point_fields[i];
      EXPECT_EQ(a.name, b.name);
      EXPECT_EQ(a.values, b.values) << a.name;
      EXPECT_EQ(a.is_integer, b.is_integer) << a.name;
      EXPECT_EQ(a.source_bytes, b.source_bytes) << a.name;
    }
    EXPECT_GE(reports, 1) << file;
    EXPECT_EQ(last, 1) << file;
  }
}

// Files found by fuzz/mesh_file_fuzzer on which VTK's own readers crash (fuzz/known): in a child
// they are an InvalidArgument naming the file and what happened.
TEST(IsolatedReadTest, AFileVtkCrashesOnIsAnErrorNotACrash) {
  const std::filesystem::path dir = MakeTempDir("isolated_crash");
  testing::WriteVtkCrashFiles(dir, ACTOPO_SOURCE_DIR);
  for (const testing::VtkCrashFile& f : testing::kVtkCrashFiles) {
    const std::string name = f.name;
    const std::filesystem::path path = dir / name;
    absl::StatusOr<Mesh> mesh = ReadMeshIsolated(path.string(), Isolated());
    ASSERT_FALSE(mesh.ok()) << name;
    EXPECT_EQ(mesh.status().code(), absl::StatusCode::kInvalidArgument) << mesh.status();
    EXPECT_THAT(std::string(mesh.status().message()), AllOf(HasSubstr(name), HasSubstr("crashed")));
  }
}

TEST(IsolatedReadTest, ErrorsOfTheReaderComeBackAsTheyAre) {
  const std::filesystem::path dir = MakeTempDir("isolated_errors");
  const std::string garbage = (dir / "garbage.vtu").string();
  { std::ofstream(garbage) << "not a VTK file"; }
  absl::StatusOr<Mesh> in_process = ReadMesh(garbage);
  absl::StatusOr<Mesh> isolated = ReadMeshIsolated(garbage, Isolated());
  ASSERT_FALSE(isolated.ok());
  EXPECT_EQ(isolated.status(), in_process.status());
  EXPECT_EQ(ReadMeshIsolated((dir / "missing.vtu").string(), Isolated()).status().code(),
            absl::StatusCode::kNotFound);
}

TEST_F(DataTest, CancellingKillsTheReader) {
  std::atomic<bool> cancel{false};
  const Progress cancelling(
      {.cancel = &cancel, .report = [&](std::string_view, double) { cancel = true; }});
  absl::StatusOr<Mesh> mesh =
      ReadMeshIsolated(DataFile("isabel02_s2_tet.vtu"), Isolated(), cancelling);
  EXPECT_EQ(mesh.status().code(), absl::StatusCode::kCancelled) << mesh.status();
  // Cancelled before the start: no child at all.
  EXPECT_EQ(
      ReadMeshIsolated(DataFile("isabel02_s2_tet.vtu"), Isolated(), cancelling).status().code(),
      absl::StatusCode::kCancelled);
}

TEST_F(DataTest, AdmitSeesTheCountsBeforeAnythingIsAllocated) {
  MeshShape seen;
  IsolatedReadOptions options = Isolated();
  options.admit = [&](const MeshShape& shape) {
    seen = shape;
    return absl::ResourceExhaustedError("too big for the test");
  };
  absl::StatusOr<Mesh> mesh = ReadMeshIsolated(DataFile("fertility_tet.vtu"), options);
  EXPECT_EQ(mesh.status(), absl::ResourceExhaustedError("too big for the test"));
  EXPECT_EQ(seen.vertices, 14570);
  EXPECT_EQ(seen.tetrahedra, 60948);
  EXPECT_EQ(seen.point_fields, 2);
}

TEST_F(DataTest, AReaderOverItsMemoryLimitIsResourceExhausted) {
  // 1 MiB beyond the reader's start-up use cannot hold isabel02: its arrays alone (points,
  // tetrahedra and two fields) exceed it.
  absl::StatusOr<Mesh> mesh =
      ReadMeshIsolated(DataFile("isabel02_s2_tet.vtu"), Isolated(int64_t(1) << 20));
  if (!IsolatedReadLimitsMemory()) {
    // Sanitizer builds run the reader without a limit (the shadow memory would exceed any).
    EXPECT_TRUE(mesh.ok()) << mesh.status();
    return;
  }
  EXPECT_EQ(mesh.status().code(), absl::StatusCode::kResourceExhausted) << mesh.status();
  EXPECT_THAT(std::string(mesh.status().message()), HasSubstr("isabel02_s2_tet.vtu"));
}

TEST_F(DataTest, AReaderThatCannotStartIsNamed) {
  IsolatedReadOptions options = Isolated();
  options.reader = "/nonexistent/actopo-read-mesh";
  absl::StatusOr<Mesh> mesh = ReadMeshIsolated(DataFile("fertility_tet.vtu"), options);
  EXPECT_EQ(mesh.status().code(), absl::StatusCode::kInternal);
  EXPECT_THAT(std::string(mesh.status().message()), HasSubstr("/nonexistent/actopo-read-mesh"));
}

}  // namespace
}  // namespace actopo::io
