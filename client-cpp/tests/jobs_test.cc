// Jobs: results equal upstream TTK's, arrays, progress, parameters, cancellation and deadlines.

#include <algorithm>
#include <array>
#include <future>
#include <map>
#include <stdexcept>
#include <string>
#include <thread>

#include "tests/testing/fixture.h"

namespace actopo::client::testing {
namespace {

using absl::StatusCode;

// A job's result, checked against upstream TTK's (expected-ttk.json) where TTK has one: the
// summary's fields, and what the streamed arrays hold (the critical points themselves, the
// critical cells per dimension, the diagram's pairs). topo-relations has no TTK counterpart: its
// totals are checked against actopo-bench's.
class JobResultTest : public ServerTest, public ::testing::WithParamInterface<const char*> {};

// Every field TTK's reference and our summary share is equal, and the summary lacks none of
// TTK's but these, which only the reference lists.
void ExpectSummaryEqualsTtk(const nlohmann::json& summary, const nlohmann::json& ttk) {
  for (const auto& [key, value] : ttk.items()) {
    if (key == "total" || key == "vertices" || key == "lines") continue;
    ASSERT_TRUE(summary.contains(key)) << key << " missing from " << summary.dump();
    EXPECT_EQ(summary[key], value) << key;
  }
}

TEST_P(JobResultTest, EqualsTtkAndArraysAreComplete) {
  const std::string algorithm = GetParam();
  const std::string session = Open(Fertility(), {.scalar = "eigenfunction4"});
  std::vector<double> progress;
  std::string accepted;
  absl::StatusOr<JobResult> result =
      client().RunJob(session, algorithm, {},
                      {.digests = true,
                       .progress = [&](double f) { progress.push_back(f); },
                       .on_accepted = [&](const std::string& id) { accepted = id; }});
  ASSERT_OK(result);
  EXPECT_EQ(result->algorithm, algorithm);
  EXPECT_EQ(result->job_id, accepted);
  EXPECT_EQ(result->job_id.rfind("job", 0), 0u);
  ASSERT_FALSE(progress.empty());
  for (double f : progress) {
    EXPECT_GE(f, 0.0);
    EXPECT_LE(f, 1.0);
  }
  EXPECT_GT(result->stats.run_seconds, 0.0);
  const nlohmann::json summary = nlohmann::json::parse(result->summary_json);
  const std::string file = "fertility_tet.vtu", field = "eigenfunction4";

  if (algorithm == "critical-points") {
    const nlohmann::json ttk = TtkReference(file, field, "critical_points");
    ExpectSummaryEqualsTtk(summary, ttk);
    // The streamed points are TTK's: (vertex, type) for each, in any order.
    absl::StatusOr<std::vector<int32_t>> ids =
        result->Get<int32_t>("critical_points/ttkVertexScalarField");
    absl::StatusOr<std::vector<int8_t>> types = result->Get<int8_t>("critical_points/CriticalType");
    ASSERT_OK(ids);
    ASSERT_OK(types);
    ASSERT_EQ(ids->size(), types->size());
    std::vector<std::array<int64_t, 2>> streamed, expected;
    for (size_t i = 0; i < ids->size(); ++i) streamed.push_back({(*ids)[i], (*types)[i]});
    for (const auto& v : ttk["vertices"]) expected.push_back({v[0], v[1]});
    std::sort(streamed.begin(), streamed.end());
    std::sort(expected.begin(), expected.end());
    EXPECT_EQ(streamed, expected);
    const Array* points = result->Find("critical_points/Points");
    ASSERT_NE(points, nullptr);
    EXPECT_EQ(points->shape, (std::vector<int64_t>{int64_t(ids->size()), 3}));
    EXPECT_OK(points->As<double>());
    EXPECT_OK(result->Get<double>("critical_points/eigenfunction4"));
    EXPECT_OK(result->Get<int8_t>("critical_points/IsOnBoundary"));
  } else if (algorithm == "discrete-gradient") {
    const nlohmann::json ttk = TtkReference(file, field, "discrete_gradient");
    ExpectSummaryEqualsTtk(summary, ttk);
    // The streamed critical cells, counted per dimension, are TTK's.
    absl::StatusOr<std::vector<int8_t>> dims = result->Get<int8_t>("critical_cells/CellDimension");
    ASSERT_OK(dims);
    std::vector<int64_t> per_dimension(4, 0);
    for (int8_t d : *dims) ++per_dimension.at(d);
    EXPECT_EQ(per_dimension, ttk["critical_cells"].get<std::vector<int64_t>>());
    EXPECT_OK(result->Get<int32_t>("critical_cells/CellId"));
  } else if (algorithm == "topo-relations") {
    const nlohmann::json expected = BenchResult(file, field, algorithm);
    ASSERT_FALSE(expected.is_null());
    EXPECT_EQ(summary, expected) << "client: " << summary.dump() << "\nbench:  " << expected.dump();
    EXPECT_TRUE(result->arrays.empty());
  } else if (algorithm == "persistence-diagram") {
    const nlohmann::json ttk = TtkReference(file, field, "persistence_diagram");
    ExpectSummaryEqualsTtk(summary, ttk);
    absl::StatusOr<std::vector<PersistencePair>> pairs = result->PersistencePairs();
    ASSERT_OK(pairs);
    EXPECT_EQ(int64_t(pairs->size()), ttk["pairs"].get<int64_t>());
    EXPECT_OK(result->Get<int32_t>("diagram/CriticalType"));
    EXPECT_OK(result->Get<float>("diagram/Coordinates"));
    EXPECT_OK(result->Get<int32_t>("persistence_curve/NumberOfPairs"));
  } else {
    const nlohmann::json ttk = TtkReference(file, field, "morse_smale");
    ExpectSummaryEqualsTtk(summary, ttk);
    absl::StatusOr<std::vector<int32_t>> labels =
        result->Get<int32_t>("segmentation/MorseSmaleManifold");
    ASSERT_OK(labels);
    EXPECT_EQ(labels->size(), 14570u);
    absl::StatusOr<std::vector<int64_t>> offsets = result->Get<int64_t>("separatrices/Offsets");
    ASSERT_OK(offsets);
    const Array* points = result->Find("separatrices/Points");
    ASSERT_NE(points, nullptr);
    EXPECT_EQ(offsets->back(), points->shape[0]);
    const nlohmann::json& separatrices = ttk["separatrices"];
    EXPECT_EQ(int64_t(offsets->size()) - 1, separatrices["descending"].get<int64_t>() +
                                                separatrices["ascending"].get<int64_t>() +
                                                separatrices["saddle_connectors"].get<int64_t>());
    EXPECT_OK(result->Get<int8_t>("separatrices/SeparatrixType"));
    EXPECT_OK(result->Get<int32_t>("critical_points/ManifoldSize"));
  }
  absl::StatusOr<SessionStats> stats = client().Stats(session);
  ASSERT_OK(stats);
  EXPECT_EQ(stats->jobs.count, 1);
}

INSTANTIATE_TEST_SUITE_P(Fertility, JobResultTest,
                         ::testing::Values("topo-relations", "critical-points", "discrete-gradient",
                                           "morse-smale", "persistence-diagram"));

TEST_F(ServerTest, SummaryOnlyAndParameters) {
  const std::string session = Open(LoadSample("jittered:8"), {.structure = Structure::kCompact});
  absl::StatusOr<JobResult> lean =
      client().RunJob(session, "morse_smale", {}, {.include_arrays = false});
  ASSERT_OK(lean);
  EXPECT_EQ(lean->algorithm, "morse-smale");
  EXPECT_TRUE(lean->arrays.empty());
  EXPECT_TRUE(nlohmann::json::parse(lean->summary_json).contains("critical_cells"));

  absl::StatusOr<JobResult> relations = client().RunJob(session, "topo-relations");
  ASSERT_OK(relations);
  EXPECT_TRUE(relations->arrays.empty());  // topo-relations has no arrays
  EXPECT_TRUE(nlohmann::json::parse(relations->summary_json).contains("relation_totals"));

  EXPECT_OK(client().RunJob(session, "critical-points", {{"boundary_rule", "none"}}));
  EXPECT_TRUE(HasError(client().RunJob(session, "critical-points", {{"boundary_rule", "maybe"}}),
                       StatusCode::kInvalidArgument, "boundary_rule: unknown value 'maybe'"));
  EXPECT_TRUE(HasError(client().RunJob(session, "critical-points", {{"speed", "fast"}}),
                       StatusCode::kInvalidArgument, "unknown parameter 'speed'"));
  EXPECT_TRUE(HasError(client().RunJob("session-guess", "critical-points"), StatusCode::kNotFound,
                       "session-guess"));
}

// JobOptions::trace: the trace-event JSON of the job, whose waits are the job's misses.
TEST_F(ServerTest, TraceOfAJob) {
  const std::string session =
      Open(LoadSample("jittered:16"), {.consumers = 2, .producers = 2, .buffer_ratio = 0.05});
  absl::StatusOr<JobResult> traced =
      client().RunJob(session, "critical-points", {}, {.include_arrays = false, .trace = true});
  ASSERT_OK(traced);
  const nlohmann::json trace = nlohmann::json::parse(traced->trace);
  std::map<int64_t, std::string> threads;  // tid -> row name
  for (const nlohmann::json& e : trace["traceEvents"]) {
    if (e["ph"] == "M" && e["name"] == "thread_name") threads[e["tid"]] = e["args"]["name"];
  }
  std::vector<std::string> phases;
  std::map<std::string, int64_t> produced;  // spans per producer role
  int64_t waits = 0, events = 0;
  for (const nlohmann::json& e : trace["traceEvents"]) {
    if (e["ph"] == "M") continue;
    ++events;
    if (e["cat"] == "phase") phases.push_back(e["name"]);
    if (e["name"] == "wait") ++waits;
    if (e["cat"] == "leader" || e["cat"] == "worker") {
      const std::string role = e["cat"];
      ++produced[role];
      // A producer's span is on its own row: "leader N" or "worker N.M".
      EXPECT_EQ(threads[e["tid"]].substr(0, role.size()), role);
    }
  }
  EXPECT_EQ(phases, (std::vector<std::string>{"start engine", "critical-points", "results"}));
  EXPECT_EQ(waits, traced->stats.engine.misses);
  EXPECT_GT(waits, 0);
  EXPECT_EQ(trace["otherData"]["events"].get<int64_t>(), events);
  std::vector<std::string> names;
  for (const auto& [tid, name] : threads) names.push_back(name);
  for (const char* name : {"job", "consumer 0", "consumer 1"}) {
    EXPECT_NE(std::find(names.begin(), names.end(), name), names.end()) << name;
  }
  // How much the producers compute depends on the schedule (with a consumer per core they run
  // at idle priority and may compute nothing); the statistics count every traced span.
  EXPECT_LE(produced["leader"], traced->stats.engine.leader_relations);
  EXPECT_LE(produced["worker"], traced->stats.engine.worker_relations);

  absl::StatusOr<JobResult> plain =
      client().RunJob(session, "critical-points", {}, {.include_arrays = false});
  ASSERT_OK(plain);
  EXPECT_TRUE(plain->trace.empty());
}

TEST_F(ServerTest, JobCallbackMayThrow) {
  const std::string session = Open(LoadSample("jittered:12"), {.structure = Structure::kCompact});
  EXPECT_THROW(client().RunJob(session, "morse-smale", {},
                               {.progress = [](double) { throw std::runtime_error("stop"); }}),
               std::runtime_error);
}

// The first job on a mesh that reads faces reports their build (phase "faces", 0 to 1) before
// its run, and their time in its stats; `progress` gets the run's fractions only,
// `phase_progress` every report. The next job finds the faces built.
TEST_F(ServerTest, AJobReportsItsPhases) {
  const std::string session =
      Open(LoadSample("jittered:10", 50), {.structure = Structure::kCompact});
  std::vector<double> run;
  std::vector<JobProgress> reports;
  absl::StatusOr<JobResult> first =
      client().RunJob(session, "discrete-gradient", {},
                      {.include_arrays = false,
                       .progress = [&](double f) { run.push_back(f); },
                       .phase_progress = [&](const JobProgress& p) { reports.push_back(p); }});
  ASSERT_OK(first);
  EXPECT_GT(first->stats.faces_seconds, 0.0);
  absl::StatusOr<JobResult> again =
      client().RunJob(session, "discrete-gradient", {}, {.include_arrays = false});
  ASSERT_OK(again);
  EXPECT_EQ(again->stats.faces_seconds, 0.0);
  ASSERT_GE(reports.size(), 3u);
  EXPECT_EQ(reports.front().phase, "faces");
  EXPECT_EQ(reports.front().fraction, 0.0);
  const auto first_run = std::find_if(reports.begin(), reports.end(),
                                      [](const JobProgress& p) { return p.phase != "faces"; });
  ASSERT_NE(first_run, reports.begin());
  EXPECT_EQ((first_run - 1)->fraction, 1.0);
  std::vector<double> reported_run;
  double elapsed = 0;
  for (auto p = reports.begin(); p != reports.end(); ++p) {
    EXPECT_GE(p->elapsed_seconds, elapsed);
    elapsed = p->elapsed_seconds;
    if (p >= first_run) {
      EXPECT_EQ(p->phase, "run");
      reported_run.push_back(p->fraction);
    }
  }
  EXPECT_EQ(run, reported_run);
  EXPECT_TRUE(std::is_sorted(run.begin(), run.end()));
  ASSERT_FALSE(run.empty());
  EXPECT_NEAR(run.back(), 1.0, 1e-9);
}

// Waits until the server says no job runs on `session`.
void WaitIdle(Client& client, const std::string& session) {
  EXPECT_TRUE(WaitUntil([&] {
    absl::StatusOr<SessionInfo> info = client.GetSession(session);
    return !info.ok() || info->running_job_id.empty();
  })) << "the job on "
      << session << " did not stop";
}

// Every job below is held by the server before it runs (Hold("RunJob")), so that it surely has
// not ended when the test cancels it or lets its deadline pass.
TEST_F(ServerTest, Cancellation) {
  const std::string session = Open(LoadSample("jittered:10"), {.structure = Structure::kCompact});
  ASSERT_FALSE(session.empty());

  // CancelJob from another thread, with the id from on_accepted.
  {
    std::unique_ptr<WorkHold> hold = Hold("RunJob");
    std::promise<std::string> job_id;
    std::future<absl::StatusOr<JobResult>> run = std::async(std::launch::async, [&] {
      return client().RunJob(session, "topo-relations", {},
                             {.on_accepted = [&](const std::string& id) { job_id.set_value(id); }});
    });
    const std::string id = job_id.get_future().get();
    ASSERT_TRUE(hold->WaitHeld());
    absl::StatusOr<SessionInfo> busy = client().GetSession(session);
    ASSERT_OK(busy);
    EXPECT_EQ(busy->running_job_id, id);
    EXPECT_TRUE(HasError(client().RunJob(session, "critical-points"),
                         StatusCode::kFailedPrecondition, "is running job"));
    ASSERT_OK(client().CancelJob(id));
    hold->Release();
    EXPECT_TRUE(HasError(run.get(), StatusCode::kCancelled));
    EXPECT_TRUE(HasError(client().CancelJob(id), StatusCode::kNotFound, id));
    WaitIdle(client(), session);
  }

  // A CancelToken cancelled from another thread once the job is held.
  {
    std::unique_ptr<WorkHold> hold = Hold("RunJob");
    CancelToken cancel;
    std::thread canceller([&] {
      if (hold->WaitHeld()) cancel.Cancel();
    });
    absl::StatusOr<JobResult> cancelled =
        client().RunJob(session, "topo-relations", {}, {.cancel = cancel});
    canceller.join();
    EXPECT_TRUE(HasError(cancelled, StatusCode::kCancelled));
    hold->Release();
    WaitIdle(client(), session);
  }

  // A job deadline, passed while the job is held.
  {
    std::unique_ptr<WorkHold> hold = Hold("RunJob");
    EXPECT_TRUE(HasError(
        client().RunJob(session, "topo-relations", {}, {.timeout = std::chrono::seconds(1)}),
        StatusCode::kDeadlineExceeded));
    EXPECT_TRUE(hold->WaitHeld(std::chrono::milliseconds(0))) << "the job was not held";
    hold->Release();
    WaitIdle(client(), session);
  }

  // The session is usable again.
  EXPECT_OK(client().RunJob(session, "critical-points", {}, {.include_arrays = false}));
}

TEST_F(ServerTest, ClosingTheSessionCancelsItsJob) {
  absl::StatusOr<SessionInfo> session =
      client().OpenSession(LoadSample("jittered:10"), {.structure = Structure::kCompact});
  ASSERT_OK(session);
  std::unique_ptr<WorkHold> hold = Hold("RunJob");
  std::future<absl::StatusOr<JobResult>> run = std::async(std::launch::async, [&] {
    return client().RunJob(session->session_id, "topo-relations", {});
  });
  ASSERT_TRUE(hold->WaitHeld());
  ASSERT_OK(client().CloseSession(session->session_id));
  hold->Release();
  const absl::StatusOr<JobResult> result = run.get();
  EXPECT_FALSE(result.ok());
  EXPECT_EQ(result.status().code(), StatusCode::kCancelled) << result.status();
}

}  // namespace
}  // namespace actopo::client::testing
