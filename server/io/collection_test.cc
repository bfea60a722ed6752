#include "server/io/collection.h"

#include <algorithm>
#include <filesystem>
#include <fstream>

#include "gmock/gmock.h"
#include "gtest/gtest.h"
#include "server/core/status_macros.h"
#include "server/io/test_data.h"
#include "server/io/vtk_reader.h"

namespace actopo::io {
namespace {

using testing::DataTest;
using ::testing::HasSubstr;
using testing::MakeTempDir;

class CollectionTest : public DataTest {};

std::string WritePvd(const std::filesystem::path& dir, const std::vector<std::string>& files) {
  std::ofstream out(dir / "series.pvd");
  out << "<?xml version=\"1.0\"?>\n<VTKFile type=\"Collection\" version=\"0.1\">\n<Collection>\n";
  for (size_t k = 0; k < files.size(); ++k) {
    out << "<DataSet timestep=\"" << 10 * k << "\" file=\"" << files[k] << "\"/>\n";
  }
  out << "</Collection>\n</VTKFile>\n";
  return (dir / "series.pvd").string();
}

TEST_F(CollectionTest, ReadsTheStepsOfParaViewsCollection) {
  const auto steps = ReadCollection(DataFile("isabel_series_s2/isabel_series.pvd"));
  ASSERT_TRUE(steps.ok()) << steps.status();
  ASSERT_EQ(steps->size(), 4u);
  EXPECT_EQ((*steps)[0].time, 2);
  EXPECT_EQ((*steps)[3].time, 5);
  EXPECT_EQ(std::filesystem::path((*steps)[1].path).filename(), "isabel_03_s2_tet.vtu");
  EXPECT_TRUE(std::filesystem::exists((*steps)[1].path));
}

TEST_F(CollectionTest, ASeriesIsOneMeshWithEveryStepsFieldEqualToTheSingleFileSeries) {
  const auto series = ReadMesh(DataFile("isabel_series_s2/isabel_series.pvd"));
  ASSERT_TRUE(series.ok()) << series.status();
  // The same members in TTK's one-file convention.
  const auto together = ReadMesh(DataFile("isabel_series_s2_tet.vtu"));
  ASSERT_TRUE(together.ok()) << together.status();
  EXPECT_EQ(series->points, together->points);
  EXPECT_EQ(series->tetrahedra, together->tetrahedra);
  ASSERT_EQ(series->point_fields.size(), 4u);
  const char* members[] = {"velocityMag_02", "velocityMag_03", "velocityMag_04", "velocityMag_05"};
  for (int k = 0; k < 4; ++k) {
    const PointField& field = series->point_fields[k];
    EXPECT_EQ(field.name, "velocityMag_" + std::to_string(k));
    ASSERT_TRUE(field.time.has_value());
    EXPECT_EQ(*field.time, 2 + k);
    EXPECT_EQ(field.values, together->FindField(members[k])->values) << members[k];
  }
}

TEST_F(CollectionTest, FilesThatDifferAreNamed) {
  const std::filesystem::path dir = MakeTempDir("collection_differs");
  std::filesystem::copy_file(DataFile("fertility_tet.vtu"), dir / "a.vtu");
  std::filesystem::copy_file(DataFile("casting_tet.vtu"), dir / "b.vtu");
  const absl::Status other = ReadMesh(WritePvd(dir, {"a.vtu", "a.vtu", "b.vtu"})).status();
  EXPECT_EQ(other.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(other.message(), HasSubstr("b.vtu: has 14756 points, not 14570"));
  const absl::Status missing = ReadMesh(WritePvd(dir, {"a.vtu", "nope.vtu"})).status();
  EXPECT_EQ(missing.code(), absl::StatusCode::kNotFound);
  EXPECT_THAT(missing.message(), HasSubstr("step 1: "));
  EXPECT_THAT(missing.message(), HasSubstr("nope.vtu: no such file"));
  std::ofstream(dir / "bad.pvd") << "<VTKFile><NoCollection/></VTKFile>";
  EXPECT_THAT(ReadCollection((dir / "bad.pvd").string()).status().message(),
              HasSubstr("no <Collection> element"));
  std::ofstream(dir / "empty.pvd") << "<VTKFile><Collection></Collection></VTKFile>";
  EXPECT_THAT(ReadCollection((dir / "empty.pvd").string()).status().message(),
              HasSubstr("lists no DataSet"));
  std::filesystem::remove_all(dir);
}

TEST(ReadSteps, JoinsTheStepsAndReportsReadingOnceFromZeroToOne) {
  const std::vector<CollectionStep> steps = {{"a.vtu", 0.5}, {"b.vtu", 1.5}, {"c.vtu", 2.5}};
  std::vector<int> fields_before;
  const StepReader read = [&](const std::string& file, int before,
                              const Progress& progress) -> absl::StatusOr<Mesh> {
    fields_before.push_back(before);
    for (double f : {0.0, 0.5, 1.0}) RETURN_IF_ERROR(progress.Update("read", f));
    Mesh mesh;
    mesh.points = {0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1};
    mesh.tetrahedra = {0, 1, 2, 3};
    mesh.point_fields.push_back({.name = "f", .values = {1, 2, 3, double(file[0])}});
    return mesh;
  };
  std::vector<double> reported;
  const Progress progress({.report = [&](std::string_view phase, double fraction) {
    EXPECT_EQ(phase, "read");
    reported.push_back(fraction);
  }});
  const absl::StatusOr<Mesh> joined = ReadSteps(steps, read, "three", progress);
  ASSERT_TRUE(joined.ok()) << joined.status();
  ASSERT_EQ(joined->point_fields.size(), 3u);
  for (int k = 0; k < 3; ++k) {
    EXPECT_EQ(joined->point_fields[k].name, "f_" + std::to_string(k));
    EXPECT_EQ(joined->point_fields[k].time, steps[k].time);
    EXPECT_EQ(joined->point_fields[k].values[3], double('a' + k));
  }
  EXPECT_EQ(fields_before, (std::vector<int>{0, 1, 2}));
  ASSERT_FALSE(reported.empty());
  EXPECT_TRUE(std::is_sorted(reported.begin(), reported.end()));
  EXPECT_EQ(reported.front(), 0);
  EXPECT_EQ(reported.back(), 1);
  EXPECT_THAT(ReadSteps({}, read, "none", {}).status().message(), HasSubstr("none: no files"));
}

TEST(SeriesFieldName, PadsTheStepToTheLastOnesWidth) {
  EXPECT_EQ(SeriesFieldName("f", 3, 4), "f_3");
  EXPECT_EQ(SeriesFieldName("f", 3, 12), "f_03");
  EXPECT_EQ(SeriesFieldName("f", 11, 12), "f_11");
  EXPECT_EQ(SeriesFieldName("f", 7, 1000), "f_007");
}

}  // namespace
}  // namespace actopo::io
