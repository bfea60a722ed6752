// Jobs over several fields: each field's result equals a job on that field alone; the
// diagram-distance matrices of the Isabel series equal actopo-bench's; a series loaded from a
// list of files equals its .pvd; tracking's summary agrees with its arrays and with the
// distances.
#include <algorithm>
#include <cmath>
#include <set>

#include "tests/testing/fixture.h"

namespace actopo::client::testing {
namespace {

using absl::StatusCode;

constexpr char kIsabel[] = "isabel_series_s2_tet.vtu";  // 12 members of the Isabel series

// The Isabel series, loaded once for the binary (the server goes at the end).
std::string Isabel(Client& client) {
  static const std::string id = [&] {
    absl::StatusOr<MeshInfo> mesh = client.LoadMesh(kIsabel);
    EXPECT_TRUE(mesh.ok()) << mesh.status();
    return mesh.ok() ? mesh->mesh_id : std::string();
  }();
  return id;
}

TEST_F(ServerTest, EachFieldsResultEqualsAJobOnItAlone) {
  const std::string mesh = LoadSample("jittered:8");
  const std::vector<std::string> fields = {"height", "scalar"};
  for (const char* algorithm : {"critical-points", "persistence-diagram"}) {
    SCOPED_TRACE(algorithm);
    const std::string session = Open(mesh, {.structure = Structure::kCompact});
    std::vector<std::string> arrived;
    std::vector<double> progress;
    absl::StatusOr<JobResult> result =
        client().RunJob(session, algorithm, {},
                        {.digests = true,
                         .progress = [&](double f) { progress.push_back(f); },
                         .fields = fields,
                         .on_field = [&](const FieldResult& f) { arrived.push_back(f.field); }});
    ASSERT_OK(result);
    EXPECT_EQ(nlohmann::json::parse(result->summary_json), nlohmann::json({{"fields", fields}}));
    EXPECT_EQ(arrived, fields);
    EXPECT_TRUE(result->arrays.empty());  // every array is a field's
    ASSERT_EQ(result->fields.size(), 2u);
    ASSERT_FALSE(progress.empty());
    EXPECT_TRUE(std::is_sorted(progress.begin(), progress.end()));
    EXPECT_NEAR(progress.back(), 1.0, 1e-9);

    for (size_t i = 0; i < fields.size(); ++i) {
      SCOPED_TRACE(fields[i]);
      const FieldResult& field = result->fields[i];
      EXPECT_EQ(field.field, fields[i]);
      EXPECT_EQ(field.index, int32_t(i));
      EXPECT_GE(field.run_seconds, 0.0);
      EXPECT_EQ(result->Field(fields[i]), &field);
      const std::string alone = Open(mesh, {.scalar = fields[i], .structure = Structure::kCompact});
      absl::StatusOr<JobResult> single = client().RunJob(alone, algorithm, {}, {.digests = true});
      ASSERT_OK(single);
      EXPECT_EQ(nlohmann::json::parse(field.summary_json),
                nlohmann::json::parse(single->summary_json));
      ASSERT_EQ(field.arrays.size(), single->arrays.size());
      for (const auto& [name, array] : single->arrays) {
        const Array* same = field.Find(name);
        ASSERT_NE(same, nullptr) << name;
        EXPECT_EQ(same->dtype, array.dtype) << name;
        EXPECT_EQ(same->shape, array.shape) << name;
        EXPECT_TRUE(same->data == array.data) << name;
      }
      if (std::string(algorithm) == "critical-points") {
        EXPECT_EQ(*field.Get<int8_t>("critical_points/CriticalType"),
                  *single->Get<int8_t>("critical_points/CriticalType"));
      } else {
        absl::StatusOr<std::vector<PersistencePair>> pairs = field.PersistencePairs();
        ASSERT_OK(pairs);
        EXPECT_EQ(int64_t(pairs->size()),
                  nlohmann::json::parse(single->summary_json)["pairs"].get<int64_t>());
      }
    }
  }
}

TEST_F(ServerTest, JobOverFieldsOptionsAndErrors) {
  const std::string mesh = LoadSample("jittered:6");
  const std::string session = Open(mesh, {.structure = Structure::kCompact});
  // Without keeping them, the fields go to on_field only; all_fields takes the mesh's order.
  std::vector<std::string> arrived;
  absl::StatusOr<JobResult> streamed =
      client().RunJob(session, "critical-points", {},
                      {.all_fields = true,
                       .on_field =
                           [&](const FieldResult& f) {
                             arrived.push_back(f.field);
                             EXPECT_OK(f.Get<int8_t>("critical_points/CriticalType"));
                           },
                       .keep_fields = false});
  ASSERT_OK(streamed);
  EXPECT_EQ(arrived, (std::vector<std::string>{"scalar", "height"}));
  EXPECT_TRUE(streamed->fields.empty());
  EXPECT_EQ(streamed->Field("scalar"), nullptr);

  EXPECT_TRUE(HasError(
      client().RunJob(session, "critical-points", {}, {.fields = {"scalar"}, .all_fields = true}),
      StatusCode::kInvalidArgument, "give fields or all_fields, not both"));
  EXPECT_TRUE(
      HasError(client().RunJob(session, "critical-points", {}, {.fields = {"height", "nope"}}),
               StatusCode::kNotFound, "fields[1]: "));
  EXPECT_TRUE(HasError(client().RunJob(session, "diagram-distance", {}, {.fields = {"height"}}),
                       StatusCode::kInvalidArgument, "compares at least two fields"));
  EXPECT_TRUE(HasError(client().RunJob(session, "tracking"), StatusCode::kInvalidArgument,
                       "compares at least two fields"));
  // Another algorithm's result has no matrix, nor tracking figures.
  EXPECT_TRUE(HasError(streamed->Distances(), StatusCode::kNotFound, "diagram-distance"));
  EXPECT_TRUE(HasError(streamed->Tracking(), StatusCode::kNotFound, "tracking"));
}

TEST_F(ServerTest, DiagramDistancesOfTheIsabelSeries) {
  const std::string mesh = Isabel(client());
  ASSERT_FALSE(mesh.empty());
  absl::StatusOr<MeshInfo> info = client().GetMesh(mesh);
  ASSERT_OK(info);
  ASSERT_EQ(info->fields.size(), 12u);
  // Six of the twelve members, from two clusters, keep the test short.
  const std::vector<std::string> names = {"velocityMag_02", "velocityMag_03", "velocityMag_04",
                                          "velocityMag_05", "velocityMag_30", "velocityMag_45"};

  const std::string session = Open(mesh, {.structure = Structure::kCompact});
  std::set<std::string> phases;
  absl::StatusOr<DistanceMatrix> matrix = client().DiagramDistances(
      session, {},
      {.phase_progress = [&](const JobProgress& p) { phases.insert(p.phase); }, .fields = names});
  ASSERT_OK(matrix);
  EXPECT_TRUE(phases.count("run") && phases.count("distances"));
  EXPECT_EQ(matrix->fields, names);
  EXPECT_EQ(matrix->p, 2.0);
  EXPECT_FALSE(matrix->essential);
  const size_t n = matrix->size();
  ASSERT_EQ(matrix->wasserstein.size(), n * n);
  ASSERT_EQ(matrix->bottleneck.size(), n * n);
  for (size_t i = 0; i < n; ++i) {
    EXPECT_EQ(matrix->Wasserstein(i, i), 0.0) << i;
    EXPECT_EQ(matrix->Bottleneck(i, i), 0.0) << i;
    for (size_t j = 0; j < n; ++j) {
      EXPECT_EQ(matrix->Wasserstein(i, j), matrix->Wasserstein(j, i)) << i << ", " << j;
      EXPECT_EQ(matrix->Bottleneck(i, j), matrix->Bottleneck(j, i)) << i << ", " << j;
      if (i == j) continue;
      EXPECT_GT(matrix->Bottleneck(i, j), 0.0) << i << ", " << j;
      // No matching costs less than its largest matched distance.
      EXPECT_GE(matrix->Wasserstein(i, j), matrix->Bottleneck(i, j)) << i << ", " << j;
    }
  }
  EXPECT_EQ(matrix->thresholds, std::vector<double>(n, 0.0));
  ASSERT_EQ(matrix->pairs.size(), n);

  // The same numbers as actopo-bench's, in-process on the file.
  std::string scalars;
  for (const std::string& name : names) scalars += (scalars.empty() ? "" : ",") + name;
  const nlohmann::json bench = BenchSeriesResult(kIsabel, scalars, "diagram-distance");
  ASSERT_FALSE(bench.is_null());
  EXPECT_EQ(bench["fields"].get<std::vector<std::string>>(), names);
  EXPECT_EQ(bench["pairs"].get<std::vector<int64_t>>(), matrix->pairs);
  for (size_t i = 0; i < n; ++i) {
    for (size_t j = 0; j < n; ++j) {
      EXPECT_EQ(bench["wasserstein"][i][j].get<double>(), matrix->Wasserstein(i, j));
      EXPECT_EQ(bench["bottleneck"][i][j].get<double>(), matrix->Bottleneck(i, j));
    }
  }

  // A threshold leaves pairs out, per field by its own range.
  absl::StatusOr<DistanceMatrix> pruned =
      client().DiagramDistances(session, {{"relative_threshold", "0.05"}, {"p", "1"}},
                                {.fields = {names[0], names[1], names[5]}});
  ASSERT_OK(pruned);
  EXPECT_EQ(pruned->fields, (std::vector<std::string>{names[0], names[1], names[5]}));
  EXPECT_EQ(pruned->p, 1.0);
  for (size_t i = 0; i < 3; ++i) {
    EXPECT_GT(pruned->thresholds[i], 0.0);
    EXPECT_LT(pruned->pairs[i], matrix->pairs[i == 2 ? 5 : i]);
  }
}

// Without fields DiagramDistances compares all of the mesh's, in its order.
TEST_F(ServerTest, DiagramDistancesOfAllFields) {
  const std::string session = Open(LoadSample("jittered:8"), {.structure = Structure::kCompact});
  absl::StatusOr<DistanceMatrix> matrix = client().DiagramDistances(session);
  ASSERT_OK(matrix);
  EXPECT_EQ(matrix->fields, (std::vector<std::string>{"scalar", "height"}));
  EXPECT_GT(matrix->Wasserstein(0, 1), 0.0);
  EXPECT_EQ(matrix->Wasserstein(0, 1), matrix->Wasserstein(1, 0));
  // With the arrays, each field's diagram comes too.
  absl::StatusOr<JobResult> job =
      client().RunJob(session, "diagram-distance", {}, {.all_fields = true});
  ASSERT_OK(job);
  absl::StatusOr<DistanceMatrix> same = job->Distances();
  ASSERT_OK(same);
  EXPECT_EQ(same->wasserstein, matrix->wasserstein);
  ASSERT_EQ(job->fields.size(), 2u);
  EXPECT_OK(job->fields[1].PersistencePairs());
}

// A list of files loads as the .pvd of them does (fields, times, ranges; progress as for a
// path); without times each file's index; each field is its file's loaded alone (the same
// persistence diagram, digests included); the errors name the file or the times.
TEST_F(ServerTest, ASeriesLoadsFromAListOfFilesAsFromItsPvd) {
  std::vector<std::string> files;
  std::string source = "files:";
  for (const char* step : {"02", "03", "04", "05"}) {
    files.push_back(std::string("isabel_series_s2/isabel_") + step + "_s2_tet.vtu");
    source += (files.size() > 1 ? "," : "") + files.back();
  }
  absl::StatusOr<MeshInfo> pvd = client().LoadMesh("isabel_series_s2/isabel_series.pvd");
  ASSERT_OK(pvd);
  meshes_.push_back(pvd->mesh_id);
  std::vector<std::string> phases;
  double last = 0;
  LoadOptions options;
  options.progress = [&](const LoadProgress& p) {
    if (phases.empty() || phases.back() != p.phase) {
      phases.push_back(p.phase);
      last = 0;
    }
    EXPECT_GE(p.fraction, last) << p.phase;  // reading too, over the four files
    last = p.fraction;
  };
  absl::StatusOr<MeshInfo> listed = client().LoadSeriesWithProgress(files, {2, 3, 4, 5}, options);
  ASSERT_OK(listed);
  meshes_.push_back(listed->mesh_id);
  EXPECT_EQ(phases, (std::vector<std::string>{"read", "partition", "encode"}));
  EXPECT_EQ(listed->name, "isabel_02_s2_tet.vtu +3 files");
  EXPECT_EQ(listed->source, source);
  EXPECT_EQ(listed->vertices, pvd->vertices);
  EXPECT_EQ(listed->tetrahedra, pvd->tetrahedra);
  ASSERT_EQ(listed->fields.size(), 4u);
  ASSERT_EQ(pvd->fields.size(), 4u);
  for (size_t k = 0; k < 4; ++k) {
    const FieldInfo& field = listed->fields[k];
    EXPECT_EQ(field.name, "velocityMag_" + std::to_string(k));
    EXPECT_EQ(field.time, std::optional<double>(2.0 + double(k)));
    EXPECT_EQ(field.name, pvd->fields[k].name);
    EXPECT_EQ(field.time, pvd->fields[k].time);
    EXPECT_EQ(field.dtype, pvd->fields[k].dtype);
    EXPECT_EQ(field.min, pvd->fields[k].min);
    EXPECT_EQ(field.max, pvd->fields[k].max);
  }

  absl::StatusOr<MeshInfo> plain = client().LoadSeries({files[0], files[1]});
  ASSERT_OK(plain);
  meshes_.push_back(plain->mesh_id);
  ASSERT_EQ(plain->fields.size(), 2u);
  absl::StatusOr<JobResult> diagrams =
      client().RunJob(Open(plain->mesh_id, {.structure = Structure::kCompact}),
                      "persistence-diagram", {}, {.digests = true, .all_fields = true});
  ASSERT_OK(diagrams);
  ASSERT_EQ(diagrams->fields.size(), 2u);
  for (size_t k = 0; k < 2; ++k) {
    SCOPED_TRACE(files[k]);
    const FieldInfo& field = plain->fields[k];
    EXPECT_EQ(field.name, "velocityMag_" + std::to_string(k));
    EXPECT_EQ(field.time, std::optional<double>(double(k)));
    absl::StatusOr<MeshInfo> alone = client().LoadMesh(files[k]);
    ASSERT_OK(alone);
    meshes_.push_back(alone->mesh_id);
    ASSERT_EQ(alone->fields.size(), 1u);
    EXPECT_EQ(field.dtype, alone->fields[0].dtype);
    EXPECT_EQ(field.min, alone->fields[0].min);
    EXPECT_EQ(field.max, alone->fields[0].max);
    absl::StatusOr<JobResult> single =
        client().RunJob(Open(alone->mesh_id, {.structure = Structure::kCompact}),
                        "persistence-diagram", {}, {.digests = true});
    ASSERT_OK(single);
    EXPECT_EQ(diagrams->fields[k].field, field.name);
    EXPECT_EQ(nlohmann::json::parse(diagrams->fields[k].summary_json),
              nlohmann::json::parse(single->summary_json));
  }

  EXPECT_TRUE(HasError(client().LoadSeries({files[0], "isabel_series_s2/nope.vtu"}),
                       StatusCode::kNotFound,
                       "files.paths[1]: 'isabel_series_s2/nope.vtu' not found"));
  const LoadOptions quiet;
  EXPECT_TRUE(HasError(client().LoadSeriesWithProgress({files[0], "../x.vtu"}, {}, quiet),
                       StatusCode::kInvalidArgument,
                       "files.paths[1]: '../x.vtu' is outside the server's data directory"));
  EXPECT_TRUE(HasError(client().LoadSeries({files[0], "fertility_tet.vtu"}),
                       StatusCode::kInvalidArgument,
                       "files: step 1: fertility_tet.vtu: has 14570 points, not 51597"));
  EXPECT_TRUE(
      HasError(client().LoadSeries({}), StatusCode::kInvalidArgument, "files.paths: empty"));
  // The times are checked before anything is sent.
  EXPECT_TRUE(HasError(client().LoadSeries(files, {1.0}), StatusCode::kInvalidArgument,
                       "files.times: 1 values for 4 paths"));
  EXPECT_TRUE(HasError(client().LoadSeries({files[0], files[1]}, {0, std::nan("")}),
                       StatusCode::kInvalidArgument, "files.times[1]: nan is not finite"));
  EXPECT_TRUE(HasError(client().LoadSeries(files, {}, {.block_size = -1}),
                       StatusCode::kInvalidArgument, "partition.block_size: -1 is negative"));
}

// A .pvd collection loads as one mesh with a field per step and its time value; tracking runs
// over them in that order.
TEST_F(ServerTest, TrackingSummaryAgreesWithItsArrays) {
  absl::StatusOr<MeshInfo> series = client().LoadMesh("isabel_series_s2/isabel_series.pvd");
  ASSERT_OK(series);
  meshes_.push_back(series->mesh_id);
  std::vector<std::string> steps;
  std::vector<std::optional<double>> times;
  for (const FieldInfo& f : series->fields) {
    steps.push_back(f.name);
    times.push_back(f.time);
  }
  EXPECT_EQ(times, (std::vector<std::optional<double>>{2.0, 3.0, 4.0, 5.0}));
  const std::string session = Open(series->mesh_id, {.structure = Structure::kCompact});
  absl::StatusOr<JobResult> result =
      client().RunJob(session, "tracking", {{"relative_threshold", "0.02"}}, {.all_fields = true});
  ASSERT_OK(result);
  absl::StatusOr<TrackingSummary> tracking = result->Tracking();
  ASSERT_OK(tracking);
  EXPECT_EQ(tracking->fields, steps);
  EXPECT_EQ(tracking->p, 2.0);
  ASSERT_EQ(tracking->trajectories_by_type.size(), 3u);
  int64_t by_type = 0;
  for (int64_t t : tracking->trajectories_by_type) by_type += t;
  EXPECT_EQ(by_type, tracking->trajectories);
  EXPECT_GT(tracking->links, 0);
  EXPECT_GE(tracking->longest, 2);
  EXPECT_LE(tracking->longest, int64_t(steps.size()));
  ASSERT_EQ(tracking->step_wasserstein.size(), steps.size() - 1);
  ASSERT_EQ(tracking->step_wasserstein_by_type.size(), steps.size() - 1);
  // Each field's diagram came with it.
  ASSERT_EQ(result->fields.size(), steps.size());
  for (const FieldResult& f : result->fields) EXPECT_OK(f.PersistencePairs()) << f.field;

  // The arrays: a point per tracked pair and step, a line of two points per link.
  absl::StatusOr<std::vector<double>> cost = result->Get<double>("tracking/Cost");
  ASSERT_OK(cost);
  EXPECT_EQ(int64_t(cost->size()), tracking->links);
  const Array* points = result->Find("tracking/Points");
  ASSERT_NE(points, nullptr);
  ASSERT_EQ(points->shape.size(), 2u);
  const int64_t k = points->shape[0];
  EXPECT_EQ(points->shape[1], 3);
  absl::StatusOr<std::vector<int64_t>> offsets = result->Get<int64_t>("tracking/Offsets");
  ASSERT_OK(offsets);
  ASSERT_EQ(int64_t(offsets->size()), tracking->links + 1);
  for (size_t i = 0; i < offsets->size(); ++i) EXPECT_EQ((*offsets)[i], int64_t(2 * i));
  for (const char* name :
       {"tracking/TimeStep", "tracking/CriticalType", "tracking/Scalar", "tracking/VertexId"}) {
    const Array* array = result->Find(name);
    ASSERT_NE(array, nullptr) << name;
    EXPECT_EQ(array->size(), k) << name;
  }
  for (const char* name : {"tracking/ConnectedComponentId", "tracking/MatchingIdentifier",
                           "tracking/ComponentLength"}) {
    const Array* array = result->Find(name);
    ASSERT_NE(array, nullptr) << name;
    EXPECT_EQ(array->size(), tracking->links) << name;
  }
  std::vector<int64_t> step = *result->Find("tracking/TimeStep")->ToInt64();
  EXPECT_EQ(*std::max_element(step.begin(), step.end()), int64_t(steps.size()) - 1);
  EXPECT_EQ(*std::min_element(step.begin(), step.end()), 0);
  // The longest trajectory has longest - 1 links.
  std::vector<int64_t> length = *result->Find("tracking/ComponentLength")->ToInt64();
  EXPECT_EQ(*std::max_element(length.begin(), length.end()), tracking->longest - 1);
  const std::vector<int64_t> component = *result->Find("tracking/ConnectedComponentId")->ToInt64();
  const std::set<int64_t> components(component.begin(), component.end());
  EXPECT_LE(int64_t(components.size()), tracking->trajectories);
  for (double c : *cost) EXPECT_GE(c, 0.0);

  // Each step's distance is the Wasserstein distance of the two fields' diagrams, which are the
  // members of the one-file series.
  const std::string members = Open(Isabel(client()), {.structure = Structure::kCompact});
  absl::StatusOr<DistanceMatrix> matrix = client().DiagramDistances(
      members, {{"relative_threshold", "0.02"}},
      {.fields = {"velocityMag_02", "velocityMag_03", "velocityMag_04", "velocityMag_05"}});
  ASSERT_OK(matrix);
  for (size_t i = 0; i + 1 < steps.size(); ++i) {
    EXPECT_DOUBLE_EQ(tracking->step_wasserstein[i], matrix->Wasserstein(i, i + 1)) << i;
  }
}

}  // namespace
}  // namespace actopo::client::testing
