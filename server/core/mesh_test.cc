#include "server/core/mesh.h"

#include <cmath>
#include <limits>

#include "absl/strings/str_cat.h"
#include "gmock/gmock.h"
#include "gtest/gtest.h"
#include "server/core/testing/status.h"
#include "server/core/testing/test_meshes.h"

namespace actopo {
namespace {

using ::testing::HasSubstr;

absl::Status Check(const Mesh& m) { return ValidateMesh(m); }

TEST(ValidateMesh, AcceptsValidMeshes) {
  EXPECT_TRUE(Check(testing::SingleTetrahedron()).ok());
  EXPECT_TRUE(Check(testing::Lattice(3, 3, 3, 5)).ok());
  EXPECT_TRUE(Check(testing::NonManifold()).ok());
}

TEST(ValidateMesh, RejectsEmptyMeshes) {
  Mesh m;
  EXPECT_THAT(Check(m).message(), HasSubstr("no vertices"));
  m.points = {0, 0, 0};
  EXPECT_EQ(Check(m).code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(Check(m).message(), HasSubstr("no tetrahedra"));
}

TEST(ValidateMesh, RejectsBadArrayLengths) {
  Mesh m = testing::SingleTetrahedron();
  m.points.push_back(1.0);
  EXPECT_THAT(Check(m).message(), HasSubstr("13 coordinates is not a multiple of 3"));
  m = testing::SingleTetrahedron();
  m.tetrahedra.push_back(0);
  EXPECT_THAT(Check(m).message(), HasSubstr("5 vertex ids is not a multiple of 4"));
}

TEST(ValidateMesh, RejectsOutOfRangeVertexIds) {
  Mesh m = testing::SingleTetrahedron();
  m.tetrahedra[2] = 7;
  const absl::Status s = Check(m);
  EXPECT_EQ(s.code(), absl::StatusCode::kOutOfRange);
  EXPECT_THAT(s.message(), HasSubstr("tetrahedron 0 has vertex id 7 outside [0, 4)"));
  m.tetrahedra[2] = -1;
  EXPECT_THAT(Check(m).message(), HasSubstr("vertex id -1"));
}

TEST(ValidateMesh, RejectsRepeatedVertex) {
  Mesh m = testing::Lattice(2, 2, 2);
  m.tetrahedra[4 * 3 + 2] = m.tetrahedra[4 * 3 + 0];
  const absl::Status s = Check(m);
  EXPECT_EQ(s.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(s.message(), HasSubstr("tetrahedron 3 repeats vertex"));
}

TEST(ValidateMesh, RejectsNonFiniteCoordinates) {
  Mesh m = testing::SingleTetrahedron();
  m.points[3 * 2 + 1] = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THAT(Check(m).message(), HasSubstr("vertex 2 has a non-finite coordinate y = nan"));
  m.points[3 * 2 + 1] = 0;
  m.points[3 * 3 + 2] = std::numeric_limits<double>::infinity();
  EXPECT_THAT(Check(m).message(), HasSubstr("vertex 3 has a non-finite coordinate z = inf"));
}

// Checked in parallel chunks: on a mesh of many chunks with several culprits, the message still
// names the first of each kind, and a culprit in the last item is found.
TEST(ValidateMesh, NamesTheFirstCulpritOfALargeMesh) {
  Mesh m = testing::Lattice(40, 40, 40);        // 64,000 vertices, 6 * 39^3 tetrahedra
  ASSERT_GT(m.points.size(), size_t(2) << 16);  // three chunks of coordinates or more
  ASSERT_TRUE(Check(m).ok());
  Mesh tets = m;
  const size_t last = tets.tetrahedra.size() / 4 - 1;
  tets.tetrahedra[4 * last + 3] = tets.tetrahedra[4 * last + 1];
  EXPECT_THAT(Check(tets).message(), HasSubstr(absl::StrCat("tetrahedron ", last, " repeats")));
  tets.tetrahedra[4 * 50000 + 1] = -5;
  tets.tetrahedra[4 * 40000 + 3] = tets.tetrahedra[4 * 40000];
  EXPECT_THAT(Check(tets).message(), HasSubstr("tetrahedron 40000 repeats vertex"));
  m.points[3 * 63999 + 2] = std::numeric_limits<double>::infinity();
  EXPECT_THAT(Check(m).message(), HasSubstr("vertex 63999 has a non-finite coordinate z = inf"));
  m.points[3 * 30000] = std::numeric_limits<double>::quiet_NaN();
  m.tetrahedra[0] = 64000;  // points are checked first
  EXPECT_THAT(Check(m).message(), HasSubstr("vertex 30000 has a non-finite coordinate x = nan"));
}

TEST(ValidateMesh, RejectsFieldOfWrongLength) {
  Mesh m = testing::SingleTetrahedron();
  m.point_fields[0].values.pop_back();
  EXPECT_THAT(Check(m).message(), HasSubstr("point field 'height' has 3 values for 4 vertices"));
}

TEST(ValidateScalarField, RejectsNaNAndInfinity) {
  PointField f{"s", {0, 1, std::nan(""), 2}};
  EXPECT_THAT(ValidateScalarField(f).message(),
              HasSubstr("'s': vertex 2 has non-finite value nan"));
  f.values[2] = -std::numeric_limits<double>::infinity();
  EXPECT_THAT(ValidateScalarField(f).message(), HasSubstr("-inf"));
}

TEST(SelectScalarField, ByNameAndDefault) {
  Mesh m = testing::SingleTetrahedron();
  m.point_fields.insert(m.point_fields.begin(), PointField{"BlockLabel", {0, 0, 1, 1}, true});
  m.point_fields.push_back({"other", {1, 2, 3, 4}});
  EXPECT_EQ(OkValue(SelectScalarField(m, "")), 1);  // integer arrays are skipped
  EXPECT_EQ(OkValue(SelectScalarField(m, "other")), 2);
  m.point_fields[0].is_integer = false;
  EXPECT_EQ(OkValue(SelectScalarField(m, "", "BlockLabel")), 1);
  const auto missing = SelectScalarField(m, "pressure");
  EXPECT_EQ(missing.status().code(), absl::StatusCode::kNotFound);
  EXPECT_THAT(missing.status().message(),
              HasSubstr("'pressure' not found; point fields: 'BlockLabel', 'height', 'other'"));
  m.point_fields[2].values[1] = std::nan("");
  EXPECT_THAT(SelectScalarField(m, "other").status().message(), HasSubstr("vertex 1"));
}

TEST(SelectScalarField, NoFloatField) {
  Mesh m = testing::SingleTetrahedron();
  m.point_fields.clear();
  EXPECT_THAT(SelectScalarField(m, "").status().message(),
              HasSubstr("no floating-point point field"));
}

}  // namespace
}  // namespace actopo
