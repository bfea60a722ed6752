#include "server/io/samples.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/strings/str_cat.h"
#include "gmock/gmock.h"
#include "gtest/gtest.h"
#include "server/io/test_data.h"

namespace actopo::io {
namespace {

using ::testing::HasSubstr;
using testing::SignedVolume6;

Mesh Make(std::string_view name) {
  absl::StatusOr<Mesh> mesh = MakeSample(name);
  EXPECT_TRUE(mesh.ok()) << mesh.status();
  return mesh.ok() ? *std::move(mesh) : Mesh{};
}

bool SameMesh(const Mesh& a, const Mesh& b) {
  if (a.points != b.points || a.tetrahedra != b.tetrahedra) return false;
  if (a.point_fields.size() != b.point_fields.size()) return false;
  for (size_t i = 0; i < a.point_fields.size(); ++i) {
    if (a.point_fields[i].name != b.point_fields[i].name ||
        a.point_fields[i].values != b.point_fields[i].values) {
      return false;
    }
  }
  return true;
}

TEST(WaveletTest, FivePointsPerAxis) {
  const Mesh mesh = Make("wavelet:5");
  EXPECT_EQ(mesh.num_vertices(), 125);
  // VTK's vtkDataSetTriangleFilter: 5 tetrahedra per voxel.
  EXPECT_EQ(mesh.num_tetrahedra(), 4 * 4 * 4 * 5);
  const PointField* rt = mesh.FindField("RTData");
  ASSERT_NE(rt, nullptr);
  EXPECT_FALSE(rt->is_integer);
  EXPECT_TRUE(SameMesh(mesh, Make("wavelet:5")));
  // Odd N is centred: -2..2.
  EXPECT_EQ(*std::min_element(mesh.points.begin(), mesh.points.end()), -2);
  EXPECT_EQ(*std::max_element(mesh.points.begin(), mesh.points.end()), 2);
}

TEST(WaveletTest, DefaultIsParaViewsExtent) {
  const Mesh mesh = Make("wavelet");
  EXPECT_EQ(mesh.num_vertices(), 21 * 21 * 21);
  EXPECT_EQ(mesh.num_tetrahedra(), 20 * 20 * 20 * 5);
  EXPECT_EQ(*std::min_element(mesh.points.begin(), mesh.points.end()), -10);
  EXPECT_EQ(*std::max_element(mesh.points.begin(), mesh.points.end()), 10);
  // ParaView shows RTData in about [37.4, 276.8] for its default Wavelet.
  const PointField* rt = mesh.FindField("RTData");
  ASSERT_NE(rt, nullptr);
  const auto [low, high] = std::minmax_element(rt->values.begin(), rt->values.end());
  EXPECT_NEAR(*low, 37.35, 0.1);
  EXPECT_NEAR(*high, 276.83, 0.1);
}

TEST(WaveletTest, EvenNHasOneMorePointBelowZero) {
  const Mesh mesh = Make("wavelet:4");
  EXPECT_EQ(mesh.num_vertices(), 64);
  EXPECT_EQ(*std::min_element(mesh.points.begin(), mesh.points.end()), -2);
  EXPECT_EQ(*std::max_element(mesh.points.begin(), mesh.points.end()), 1);
}

TEST(JitteredTest, CountsOrientationAndDeterminism) {
  const Mesh mesh = Make("jittered:4");
  EXPECT_EQ(mesh.num_vertices(), 64);
  EXPECT_EQ(mesh.num_tetrahedra(), 162);
  for (size_t t = 0; t < 162; ++t) EXPECT_GT(SignedVolume6(mesh, t), 0) << "tetrahedron " << t;
  std::vector<bool> used(64, false);
  for (SimplexId v : mesh.tetrahedra) used[v] = true;
  EXPECT_TRUE(std::all_of(used.begin(), used.end(), [](bool u) { return u; }));
  EXPECT_TRUE(SameMesh(mesh, Make("jittered:4")));
}

TEST(JitteredTest, TheBoxStaysABoxAndInteriorPointsMove) {
  const Mesh mesh = Make("jittered:5");
  const double spacing = 0.25;
  int moved = 0;
  for (int v = 0; v < mesh.num_vertices(); ++v) {
    const std::array<int, 3> index = {v % 5, (v / 5) % 5, v / 25};
    for (int axis = 0; axis < 3; ++axis) {
      const double c = mesh.points[3 * v + axis];
      const double lattice = index[axis] * spacing;
      if (index[axis] == 0 || index[axis] == 4) {
        EXPECT_EQ(c, lattice) << "vertex " << v << " axis " << axis;
      } else {
        EXPECT_LE(std::abs(c - lattice), 0.1 * spacing);
        moved += c != lattice;
      }
    }
  }
  // Per axis, the 3 interior layers of 5 x 5 points move along it.
  EXPECT_EQ(moved, 3 * (3 * 5 * 5));
}

TEST(JitteredTest, SplitIsConforming) {
  // Every triangle lies in one tetrahedron (boundary) or two; the boundary is the cube's six
  // faces with 2 triangles per square.
  const int n = 4;
  const Mesh mesh = Make("jittered:4");
  std::map<std::array<SimplexId, 3>, int> count;
  for (int t = 0; t < mesh.num_tetrahedra(); ++t) {
    for (int skip = 0; skip < 4; ++skip) {
      std::array<SimplexId, 3> face;
      for (int k = 0, j = 0; k < 4; ++k) {
        if (k != skip) face[j++] = mesh.tetrahedra[4 * t + k];
      }
      std::sort(face.begin(), face.end());
      ++count[face];
    }
  }
  int boundary = 0;
  for (const auto& [face, c] : count) {
    EXPECT_LE(c, 2);
    boundary += c == 1;
  }
  EXPECT_EQ(boundary, 6 * (n - 1) * (n - 1) * 2);
}

TEST(JitteredTest, Fields) {
  const Mesh mesh = Make("jittered");
  EXPECT_EQ(mesh.num_vertices(), 32 * 32 * 32);
  EXPECT_EQ(mesh.num_tetrahedra(), 6 * 31 * 31 * 31);
  const PointField* height = mesh.FindField("height");
  const PointField* scalar = mesh.FindField("scalar");
  ASSERT_NE(height, nullptr);
  ASSERT_NE(scalar, nullptr);
  for (int v = 0; v < mesh.num_vertices(); ++v)
    EXPECT_EQ(height->values[v], mesh.points[3 * v + 2]);
  const auto [low, high] = std::minmax_element(scalar->values.begin(), scalar->values.end());
  EXPECT_LT(*low, -1);
  EXPECT_GT(*high, 1);
}

TEST(SamplesTest, BadNamesAreRefused) {
  for (const char* name : {"wavelet:1", "wavelet:513", "wavelet:", "wavelet:x", "wavelet:5x",
                           "jittered:1", "jittered:401", "jittered:-3", "cube", "", "Wavelet"}) {
    absl::StatusOr<Mesh> mesh = MakeSample(name);
    ASSERT_FALSE(mesh.ok()) << name;
    EXPECT_EQ(mesh.status().code(), absl::StatusCode::kInvalidArgument);
    EXPECT_THAT(mesh.status().message(), HasSubstr(absl::StrCat("'", name, "'")));
    EXPECT_THAT(mesh.status().message(), HasSubstr("wavelet:N"));
    EXPECT_THAT(mesh.status().message(), HasSubstr("jittered:N"));
  }
}

TEST(SamplesTest, TheSamplePrefixIsAcceptedAndErrorsStayShort) {
  EXPECT_TRUE(SameMesh(Make("sample:jittered:4"), Make("jittered:4")));
  EXPECT_TRUE(IsSampleName("sample:wavelet:16"));
  EXPECT_TRUE(IsSampleName("wavelet:16"));
  EXPECT_FALSE(IsSampleName("wavelet:16.vtu"));
  EXPECT_FALSE(IsSampleName("fertility_tet.vtu"));
  const absl::Status unknown = MakeSample("sample:teapot").status();
  EXPECT_EQ(unknown.message(),
            "sample 'teapot': unknown sample; samples: wavelet:N (2 <= N <= 512), "
            "jittered:N (2 <= N <= 400)");
}

TEST(SamplesTest, Names) {
  const std::vector<std::string> names = SampleNames();
  ASSERT_EQ(names.size(), 2u);
  EXPECT_THAT(names[0], ::testing::StartsWith("wavelet:N  "));
  EXPECT_THAT(names[1], ::testing::StartsWith("jittered:N  "));
}

}  // namespace
}  // namespace actopo::io
