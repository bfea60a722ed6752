// Test-only: locates the shared test meshes and skips tests when they are absent.
//
//   class ReadTest : public actopo::io::testing::DataTest {};
//   TEST_F(ReadTest, Fertility) { auto mesh = ReadMesh(DataFile("fertility_tet.vtu")); ... }
//
// The directory is $ACTOPO_DATA_DIR when set, else the ACTOPO_DATA_DIR compile definition (the
// checkout's ../shared/data). A CI clone may have neither, hence the skip rather than a failure.
#ifndef ACTOPO_SERVER_IO_TEST_DATA_H_
#define ACTOPO_SERVER_IO_TEST_DATA_H_

#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <string>
#include <system_error>
#include <vector>

#include "gtest/gtest.h"
#include "server/core/mesh.h"
#include "tests/testing/skip.h"

namespace actopo::io::testing {

inline std::string DataDir() {
  const char* from_environment = std::getenv("ACTOPO_DATA_DIR");
  if (from_environment != nullptr && *from_environment != '\0') return from_environment;
  return ACTOPO_DATA_DIR;
}

class DataTest : public ::testing::Test {
 protected:
  void SetUp() override {
    if (!std::filesystem::is_directory(DataDir())) {
      ACTOPO_SKIP() << "test data directory '" << DataDir()
                    << "' not found; set ACTOPO_DATA_DIR to the folder of shared/data";
    }
  }

  static std::string DataFile(const std::string& name) { return DataDir() + "/" + name; }
};

// A fresh empty directory for the files one test writes, removed when the test program exits
// (callers use the path in one expression, so no object of theirs could own it).
inline std::filesystem::path MakeTempDir(const std::string& name) {
  static struct Made {
    std::mutex mu;
    std::vector<std::filesystem::path> dirs;
    ~Made() {
      std::error_code ignored;  // nothing to do about a directory that will not go
      for (const auto& dir : dirs) std::filesystem::remove_all(dir, ignored);
    }
  } made;
  const std::filesystem::path dir = std::filesystem::path(::testing::TempDir()) /
                                    ("actopo_io_" + name + "_" + std::to_string(::getpid()));
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  std::lock_guard<std::mutex> lock(made.mu);
  made.dirs.push_back(dir);
  return dir;
}

// Files on which VTK's own readers crash, found by fuzz/mesh_file_fuzzer (fuzz/known/), written
// to `dir` under the names given here (the fuzzer's inputs start with a format byte, skipped).
// `source_dir`: the repository (ACTOPO_SOURCE_DIR in the tests that use this).
struct VtkCrashFile {
  const char* known;  // in fuzz/known/
  const char* name;   // as written
};
inline constexpr VtkCrashFile kVtkCrashFiles[] = {
    {"legacy_vtk_points_cut_short.vtk.bin", "cut_short.vtk"},
    {"xml_compressed_block_size_zero.vtu.bin", "block_size_zero.vtu"},
};
inline void WriteVtkCrashFiles(const std::filesystem::path& dir, const std::string& source_dir) {
  for (const VtkCrashFile& f : kVtkCrashFiles) {
    std::ifstream in(source_dir + "/fuzz/known/" + f.known, std::ios::binary);
    in.ignore(1);
    std::ofstream(dir / f.name, std::ios::binary) << in.rdbuf();
  }
}

// Six times the signed volume of tetrahedron t, positive for VTK's orientation: the normal
// (p1 - p0) x (p2 - p0) of the first three vertices points towards the fourth.
inline double SignedVolume6(const Mesh& mesh, size_t t) {
  const double* p[4];
  for (int k = 0; k < 4; ++k) p[k] = &mesh.points[3 * size_t(mesh.tetrahedra[4 * t + k])];
  double a[3], b[3], c[3];
  for (int i = 0; i < 3; ++i) {
    a[i] = p[1][i] - p[0][i];
    b[i] = p[2][i] - p[0][i];
    c[i] = p[3][i] - p[0][i];
  }
  return (a[1] * b[2] - a[2] * b[1]) * c[0] + (a[2] * b[0] - a[0] * b[2]) * c[1] +
         (a[0] * b[1] - a[1] * b[0]) * c[2];
}

}  // namespace actopo::io::testing

#endif  // ACTOPO_SERVER_IO_TEST_DATA_H_
