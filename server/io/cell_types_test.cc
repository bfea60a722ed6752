#include "server/io/cell_types.h"

#include <cstdint>
#include <vector>

#include "gmock/gmock.h"
#include "gtest/gtest.h"

namespace actopo::io {
namespace {

using ::testing::HasSubstr;

TEST(ValidateCellTypes, NamesTheTypesFound) {
  const std::vector<uint8_t> tets(5, 10);
  EXPECT_TRUE(ValidateCellTypes(tets).ok());
  const std::vector<uint8_t> mixed = {10, 12, 12, 5, 10, 14};
  const absl::Status s = ValidateCellTypes(mixed);
  EXPECT_EQ(s.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(s.message(), HasSubstr("only tetrahedral meshes are served"));
  EXPECT_THAT(s.message(), HasSubstr("1 triangle (VTK type 5)"));
  EXPECT_THAT(s.message(), HasSubstr("2 hexahedron (VTK type 12)"));
  EXPECT_THAT(s.message(), HasSubstr("1 pyramid (VTK type 14)"));
  const std::vector<uint8_t> surface = {5, 5, 5};
  EXPECT_THAT(ValidateCellTypes(surface).message(), HasSubstr("2D surface mesh"));
}

TEST(VtkCellTypeName, NamesLinearAndOtherCells) {
  EXPECT_EQ(VtkCellTypeName(10), "tetrahedron");
  EXPECT_EQ(VtkCellTypeName(12), "hexahedron");
  EXPECT_EQ(VtkCellTypeName(24), "quadratic cell");
  EXPECT_EQ(VtkCellTypeName(42), "higher-order or polyhedral cell");
}

}  // namespace
}  // namespace actopo::io
