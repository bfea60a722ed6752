// The session manager's job leases without gRPC (so this also runs under ThreadSanitizer):
// exactly one of many concurrent StartJob calls on a session wins, and every way a job ends
// releases its session, its threads and its id.
#include "server/service/session_manager.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <latch>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "absl/strings/match.h"
#include "server/algorithms/morse_smale.h"
#include "server/core/testing/status.h"
#include "server/io/samples.h"

namespace actopo::service {
namespace {

class SessionManagerTest : public ::testing::Test {
 protected:
  SessionManagerTest()
      : budget_(int64_t(4) << 30),
        meshes_(MeshRegistryOptions{}, &budget_),
        sessions_(SessionLimits{.max_sessions = 8, .max_engine_threads = 16}, &budget_) {}

  std::shared_ptr<Session> OpenSession(StructureKind structure = StructureKind::kCompact) {
    auto mesh = meshes_.LoadSample("jittered:6", {});
    EXPECT_TRUE(mesh.ok()) << mesh.status();
    auto session =
        sessions_.Open(*mesh, SessionOptions{.structure = WithDefaults({.kind = structure})});
    EXPECT_TRUE(session.ok()) << session.status();
    return *session;
  }

  MemoryBudget budget_;
  MeshRegistry meshes_;
  SessionManager sessions_;
};

// A loaded mesh keeps its points and fields but not its tetrahedra (the topology holds them):
// of those only the order of each one's vertices, which Morse-Smale needs, equal to InputCorners
// of the tetrahedra as given, and shared by the mesh's sessions. Its share of the memory budget
// is what it holds.
TEST_F(SessionManagerTest, ALoadedMeshKeepsItsTetrahedraCornersNotTheTetrahedra) {
  const Mesh given = OkValue(io::MakeSample("jittered:6"));
  auto mesh = meshes_.LoadSample("jittered:6", {});
  ASSERT_TRUE(mesh.ok()) << mesh.status();
  const LoadedMesh& loaded = **mesh;
  EXPECT_TRUE(loaded.mesh.tetrahedra.empty());
  EXPECT_EQ(loaded.mesh.points, given.points);
  EXPECT_EQ(loaded.topology->num_tetrahedra(), given.num_tetrahedra());
  ASSERT_NE(loaded.input_corners, nullptr);
  EXPECT_EQ(*loaded.input_corners, OkValue(InputCorners(*loaded.topology, given.tetrahedra)));
  // Not every tetrahedron came sorted: the corners carry information.
  EXPECT_TRUE(std::any_of(loaded.input_corners->begin(), loaded.input_corners->end(),
                          [](uint8_t c) { return c != 0b11100100; }));
  EXPECT_GE(loaded.bytes(), loaded.topology->bytes().total() + given.num_tetrahedra());
  EXPECT_LT(loaded.bytes(), loaded.topology->bytes().total() + int64_t(given.points.size() * 8) +
                                int64_t(given.point_fields.size() * given.num_vertices() * 8) +
                                2 * given.num_tetrahedra());
  // The load reserved its estimated peak; the mesh keeps a reservation of what it holds.
  EXPECT_LT(loaded.bytes(),
            MeshRegistry::EstimateBytes(given.num_vertices(), given.num_tetrahedra(),
                                        int(given.point_fields.size())));
  EXPECT_EQ(budget_.used(), loaded.bytes());
}

// A caller that finds the mesh's faces being built waits for that build, but only as long as it
// wants to: its cancel ends its wait, the build goes on for the caller that started it, and
// the faces are then there for everyone.
TEST_F(SessionManagerTest, AWaitForTheMeshsFacesEndsWhenItsCallerStops) {
  auto mesh = meshes_.LoadSample("jittered:6", {});
  ASSERT_TRUE(mesh.ok()) << mesh.status();
  const LoadedMesh& loaded = **mesh;
  ASSERT_FALSE(loaded.topology->has_faces());
  std::latch building(1), release(1), waiting(1);
  absl::Status built;
  std::thread builder([&] {
    bool first = true;
    built = loaded.EnsureFaces(Progress({.report = [&](std::string_view, double) {
      if (!std::exchange(first, false)) return;
      building.count_down();
      release.wait();
    }}));
  });
  building.wait();
  std::atomic<bool> cancel{false};
  absl::Status waited;
  std::thread waiter([&] {
    bool first = true;
    waited = loaded.EnsureFaces(
        Progress({.cancel = &cancel, .report = [&](std::string_view phase, double fraction) {
                    EXPECT_EQ(phase, "faces");
                    EXPECT_EQ(fraction, 0.0);  // the builder's first report, where it is held
                    if (std::exchange(first, false)) waiting.count_down();
                  }}));
  });
  waiting.wait();  // it reports from inside its wait, so it is waiting now
  cancel = true;
  waiter.join();
  EXPECT_EQ(waited.code(), absl::StatusCode::kCancelled) << waited;
  EXPECT_TRUE(absl::StrContains(waited.message(), "faces")) << waited;
  EXPECT_FALSE(loaded.topology->has_faces());
  release.count_down();
  builder.join();
  EXPECT_TRUE(built.ok()) << built;
  EXPECT_TRUE(loaded.topology->has_faces());
  EXPECT_TRUE(loaded.EnsureFaces().ok());
}

// When the build a caller waits for stops (its own caller cancelled it), the waiter builds the
// faces itself, and what the stopped build reserved goes back to the budget.
TEST_F(SessionManagerTest, AWaiterBuildsTheFacesWhenTheBuildItWaitedForStops) {
  auto mesh = meshes_.LoadSample("jittered:6", {});
  ASSERT_TRUE(mesh.ok()) << mesh.status();
  const LoadedMesh& loaded = **mesh;
  const int64_t before = budget_.used();
  std::latch building(1), waiting(1);
  std::atomic<bool> stop_builder{false};
  absl::Status stopped;
  std::thread builder([&] {
    bool first = true;
    stopped = loaded.EnsureFaces(
        Progress({.cancel = &stop_builder, .report = [&](std::string_view, double) {
                    if (!std::exchange(first, false)) return;
                    building.count_down();
                    waiting.wait();  // until the other caller waits for this build
                    stop_builder = true;
                  }}));
  });
  building.wait();
  bool first = true;
  std::vector<std::string> phases;
  const absl::Status waited =
      loaded.EnsureFaces(Progress({.report = [&](std::string_view phase, double) {
        phases.emplace_back(phase);
        if (std::exchange(first, false)) waiting.count_down();
      }}));
  builder.join();
  EXPECT_EQ(stopped.code(), absl::StatusCode::kCancelled) << stopped;
  EXPECT_TRUE(waited.ok()) << waited;
  EXPECT_TRUE(loaded.topology->has_faces());
  EXPECT_GE(phases.size(), 3u);  // the wait's report, then its own build's from 0 to 1
  EXPECT_TRUE(std::all_of(phases.begin(), phases.end(), [](auto& p) { return p == "faces"; }));
  const TopologyBytes bytes = loaded.topology->bytes();
  EXPECT_EQ(budget_.used() - before, bytes.edges + bytes.triangles);
}

TEST_F(SessionManagerTest, ExactlyOneOfManyConcurrentStartsWins) {
  const std::string id = OpenSession()->id();
  for (int round = 0; round < 5; ++round) {
    constexpr int kAttempts = 100;
    std::vector<absl::StatusOr<JobLease>> results;
    for (int i = 0; i < kAttempts; ++i) results.emplace_back(absl::UnknownError("not run"));
    std::atomic<bool> go{false};
    std::vector<std::thread> threads;
    for (int i = 0; i < kAttempts; ++i) {
      threads.emplace_back([&, i] {
        while (!go.load()) std::this_thread::yield();
        results[i] = sessions_.StartJob(id, Algorithm::kCriticalPoints);
      });
    }
    go = true;
    for (std::thread& t : threads) t.join();
    int winners = 0;
    std::string winner;
    for (const auto& r : results) {
      if (r.ok()) winner = r->job().id, ++winners;
    }
    ASSERT_EQ(winners, 1) << "round " << round;
    EXPECT_EQ(sessions_.RunningJob(id), winner);
    for (const auto& r : results) {
      if (r.ok()) continue;
      EXPECT_EQ(r.status().code(), absl::StatusCode::kFailedPrecondition) << r.status();
      EXPECT_TRUE(absl::StrContains(r.status().message(), winner)) << r.status();
    }
    results.clear();  // the winner's lease ends the job
    EXPECT_EQ(sessions_.RunningJob(id), "");
    EXPECT_EQ(sessions_.running_jobs(), 0);
    EXPECT_EQ(sessions_.threads_in_use(), 0);
  }
}

TEST_F(SessionManagerTest, LeaseHoldsThreadsAndEndsOnRelease) {
  const std::string id = OpenSession(StructureKind::kActopo)->id();
  const int idle = sessions_.threads_in_use();  // the query engine's producers
  EXPECT_GT(idle, 0);
  absl::StatusOr<JobLease> lease = sessions_.StartJob(id, Algorithm::kDiscreteGradient);
  ASSERT_TRUE(lease.ok()) << lease.status();
  EXPECT_GT(sessions_.threads_in_use(), idle);
  const std::string job = lease->job().id;
  ASSERT_TRUE(sessions_.CancelJob(job).ok());
  EXPECT_TRUE(lease->job().cancel.load());
  JobLease moved = std::move(*lease);
  lease->Release();  // moved from: no effect
  EXPECT_EQ(sessions_.RunningJob(id), job);
  moved.Release();
  moved.Release();  // idempotent
  EXPECT_EQ(sessions_.threads_in_use(), idle);
  EXPECT_EQ(sessions_.CancelJob(job).code(), absl::StatusCode::kNotFound);
  EXPECT_TRUE(sessions_.StartJob(id, Algorithm::kDiscreteGradient).ok());
}

TEST_F(SessionManagerTest, ClosingTheSessionCancelsItsJob) {
  std::shared_ptr<Session> session = OpenSession();
  absl::StatusOr<JobLease> lease = sessions_.StartJob(session->id(), Algorithm::kMorseSmale);
  ASSERT_TRUE(lease.ok());
  ASSERT_TRUE(sessions_.Close(session->id()).ok());
  EXPECT_TRUE(lease->job().cancel.load());
  // The job still holds its lease until its thread returns; then nothing is left.
  EXPECT_EQ(sessions_.running_jobs(), 1);
  lease->Release();
  EXPECT_EQ(sessions_.running_jobs(), 0);
  EXPECT_EQ(sessions_.StartJob(session->id(), Algorithm::kMorseSmale).status().code(),
            absl::StatusCode::kNotFound);
}

TEST_F(SessionManagerTest, DrainCancelsJobsAndRefusesNewOnes) {
  const std::string a = OpenSession()->id(), b = OpenSession()->id();
  absl::StatusOr<JobLease> job = sessions_.StartJob(a, Algorithm::kCriticalPoints);
  ASSERT_TRUE(job.ok());
  sessions_.Drain();
  EXPECT_TRUE(job->job().cancel.load());
  EXPECT_EQ(sessions_.StartJob(b, Algorithm::kCriticalPoints).status().code(),
            absl::StatusCode::kUnavailable);
}

TEST_F(SessionManagerTest, ThreadBudgetRefusesAJobThatDoesNotFit) {
  // A budget of 16 threads; two actopo sessions hold 3 query producers each and their jobs
  // need 2 * (1 + 3) = 8 threads: one job fits (6 + 8 = 14), a second does not.
  auto mesh = meshes_.LoadSample("jittered:6", {});
  ASSERT_TRUE(mesh.ok());
  std::vector<std::string> ids;
  for (int i = 0; i < 2; ++i) {
    auto s = sessions_.Open(*mesh, SessionOptions{.structure = {.kind = StructureKind::kActopo,
                                                                .consumers = 2,
                                                                .producers = 3,
                                                                .query_readers = 1}});
    ASSERT_TRUE(s.ok()) << s.status();
    ids.push_back((*s)->id());
  }
  absl::StatusOr<JobLease> first = sessions_.StartJob(ids[0], Algorithm::kCriticalPoints);
  ASSERT_TRUE(first.ok());
  absl::StatusOr<JobLease> second = sessions_.StartJob(ids[1], Algorithm::kCriticalPoints);
  EXPECT_EQ(second.status().code(), absl::StatusCode::kResourceExhausted) << second.status();
  first->Release();
  EXPECT_TRUE(sessions_.StartJob(ids[1], Algorithm::kCriticalPoints).ok());
}

// Readers of one session used from several threads at once answer like the explicit structure;
// more threads than readers wait their turn.
TEST_F(SessionManagerTest, ConcurrentQueriesShareTheSessionsReaders) {
  auto mesh = meshes_.LoadSample("jittered:9", {.bucket_capacity = 40});
  ASSERT_TRUE(mesh.ok());
  const SimplexId n = (*mesh)->topology->num_vertices();
  std::vector<SimplexId> all(n);
  for (SimplexId v = 0; v < n; ++v) all[v] = v;
  const auto answer = [&](Session& session, Relation r) {
    std::vector<int64_t> offsets, values;
    session.Query(r, all, offsets, values);
    return std::make_pair(offsets, values);
  };
  auto reference = sessions_.Open(
      *mesh, SessionOptions{.structure = WithDefaults({.kind = StructureKind::kExplicit})});
  ASSERT_TRUE(reference.ok());
  const Relation relations[] = {Relation::kVT, Relation::kVE, Relation::kVL};
  std::vector<std::pair<std::vector<int64_t>, std::vector<int64_t>>> expected;
  for (Relation r : relations) expected.push_back(answer(**reference, r));
  for (StructureKind kind : {StructureKind::kCompact, StructureKind::kActopo}) {
    auto session = sessions_.Open(
        *mesh, SessionOptions{
                   .structure = WithDefaults(
                       {.kind = kind, .producers = 1, .buffer_ratio = 0.05, .query_readers = 2})});
    ASSERT_TRUE(session.ok()) << session.status();
    std::atomic<int> mismatches{0};
    std::vector<std::thread> threads;
    for (int t = 0; t < 4; ++t) {
      threads.emplace_back([&, t] {
        for (int c = 0; c < 3; ++c) {
          if (answer(**session, relations[(t + c) % 3]) != expected[(t + c) % 3]) ++mismatches;
        }
      });
    }
    for (std::thread& t : threads) t.join();
    EXPECT_EQ(mismatches.load(), 0);
    const SessionStats stats = (*session)->stats();
    EXPECT_EQ(stats.queries, 12);
    EXPECT_EQ(stats.query_simplices, 12 * int64_t(n));
  }
}

// Many threads loading, opening, querying, closing and deleting against limits that cannot hold
// them all: each refusal is RESOURCE_EXHAUSTED naming what did not fit, the budget and counts
// never exceed their limits, and everything is released at the end.
TEST(ServiceLimits, HoldUnderConcurrentLoadsOpensAndCloses) {
  // The sizes of one sample mesh and one explicit session on it, measured with room to spare.
  int64_t mesh_bytes = 0, session_bytes = 0;
  {
    MemoryBudget roomy(int64_t(1) << 30);
    MeshRegistry meshes(MeshRegistryOptions{}, &roomy);
    SessionManager sessions(SessionLimits{}, &roomy);
    auto mesh = meshes.LoadSample("jittered:6", {});
    ASSERT_TRUE(mesh.ok()) << mesh.status();
    mesh_bytes = roomy.used();
    ASSERT_TRUE(sessions
                    .Open(*mesh, SessionOptions{.structure = WithDefaults(
                                                    {.kind = StructureKind::kExplicit})})
                    .ok());
    session_bytes = roomy.used() - mesh_bytes;
  }
  ASSERT_GT(mesh_bytes, 0);
  ASSERT_GT(session_bytes, 0);

  // Room for two meshes with a session each; eight threads want one of each at once.
  MemoryBudget budget(2 * (mesh_bytes + session_bytes));
  MeshRegistry meshes(MeshRegistryOptions{.max_meshes = 3}, &budget);
  SessionManager sessions(SessionLimits{.max_sessions = 2, .max_engine_threads = 16}, &budget);
  std::atomic<int> completed{0}, refused{0}, unexpected{0}, over_limit{0};
  const auto check_limits = [&] {
    if (budget.used() > budget.limit() || meshes.size() > 3 || sessions.size() > 2) ++over_limit;
  };
  const auto refusal = [&](const absl::Status& status) {
    if (status.code() == absl::StatusCode::kResourceExhausted) {
      ++refused;
    } else {
      ++unexpected;
      ADD_FAILURE() << status;
    }
  };
  std::vector<std::thread> threads;
  for (int t = 0; t < 8; ++t) {
    threads.emplace_back([&, t] {
      for (int round = 0; round < 25; ++round) {
        auto mesh = meshes.LoadSample("jittered:6", {});
        check_limits();
        if (!mesh.ok()) {
          refusal(mesh.status());
          continue;
        }
        const StructureKind kind =
            (t + round) % 2 ? StructureKind::kExplicit : StructureKind::kCompact;
        auto session =
            sessions.Open(*mesh, SessionOptions{.structure = WithDefaults({.kind = kind})});
        check_limits();
        if (session.ok()) {
          std::vector<int64_t> offsets = {0}, values;  // Query appends each row's end
          (*session)->Query(Relation::kVT, std::vector<SimplexId>{0, 1, 2}, offsets, values);
          if (offsets.size() != 4 || values.empty()) ++unexpected;
          if (absl::Status s = sessions.Close((*session)->id()); !s.ok()) ++unexpected;
          ++completed;
        } else {
          refusal(session.status());
        }
        if (absl::Status s = meshes.Delete((*mesh)->id); !s.ok()) ++unexpected;
      }
    });
  }
  for (std::thread& t : threads) t.join();
  EXPECT_EQ(unexpected.load(), 0);
  EXPECT_EQ(over_limit.load(), 0);
  EXPECT_GT(completed.load(), 0);
  EXPECT_EQ(completed.load() + refused.load(), 8 * 25);
  EXPECT_EQ(meshes.size(), 0u);
  EXPECT_EQ(sessions.size(), 0u);
  EXPECT_EQ(budget.used(), 0);
}

}  // namespace
}  // namespace actopo::service
