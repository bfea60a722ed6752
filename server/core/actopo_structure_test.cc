// The ACTOPO engine: exact relations for every prefetch mode, precompute scope, producer and
// consumer count and buffer size; a one-block buffer under many producers; shutdown while
// consumers are reading and waiting.
#include "server/core/actopo_structure.h"

#include <sched.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <future>
#include <iterator>
#include <string>
#include <thread>
#include <tuple>
#include <vector>

#include "absl/cleanup/cleanup.h"
#include "gtest/gtest.h"
#include "server/core/partition.h"
#include "server/core/process_memory.h"
#include "server/core/testing/oracle.h"
#include "server/core/testing/relation_checks.h"
#include "server/core/testing/status.h"
#include "server/core/testing/test_meshes.h"

namespace actopo {
namespace {

std::shared_ptr<const Topology> Build(const Mesh& m, int capacity) {
  return OkValue(Topology::Build(m, OctreeBlocks(m.points, {.bucket_capacity = capacity})));
}

std::unique_ptr<ActopoStructure> Create(std::shared_ptr<const Topology> topo,
                                        const ActopoStructure::Options& options) {
  auto s = ActopoStructure::Create(std::move(topo), options);
  EXPECT_TRUE(s.ok()) << s.status();
  return std::move(*s);
}

// One engine configuration; every combination is a test of its own.
struct Config {
  Prefetch prefetch;
  Precompute precompute;
  int producers;
  int consumers;
  double ratio;
  MissPolicy policy;
};

std::string Label(const Config& c) {
  return std::string(PrefetchName(c.prefetch)) + "/" + std::string(PrecomputeName(c.precompute)) +
         " P=" + std::to_string(c.producers) + " C=" + std::to_string(c.consumers) +
         " ratio=" + std::to_string(c.ratio) + " miss=" + std::string(MissPolicyName(c.policy));
}

class EveryConfiguration : public ::testing::TestWithParam<
                               std::tuple<Prefetch, Precompute, int, int, double, MissPolicy>> {
 protected:
  Config config() const {
    const auto& [prefetch, precompute, producers, consumers, ratio, policy] = GetParam();
    return {prefetch, precompute, producers, consumers, ratio, policy};
  }
};

// One reader thread per consumer, each comparing `reads` random reads and then a full sweep
// with the oracle (seeds seed, seed + 1, ...); the caller joins them.
std::vector<std::thread> CompareOnEveryConsumer(ActopoStructure& structure,
                                                const testing::RelationOracle& oracle, int seed,
                                                int reads) {
  std::vector<std::thread> threads;
  for (int k = 0; k < structure.options().consumers; ++k) {
    threads.emplace_back([&structure, &oracle, seed, reads, k] {
      auto reader = structure.NewReader();
      testing::CompareRandomAccess(reader, oracle, seed + k, reads, "random access");
      EXPECT_EQ(testing::CompareWithOracle(reader, oracle, "sweep"), 0);
    });
  }
  return threads;
}

TEST_P(EveryConfiguration, MatchesTheOracle) {
  const Config c = config();
  for (const Mesh& mesh : {testing::Lattice(5, 5, 4, 9), testing::NonManifold()}) {
    auto topo = Build(mesh, 9);
    testing::RelationOracle oracle(*topo);
    auto structure = Create(topo, {.consumers = c.consumers,
                                   .producers = c.producers,
                                   .buffer_ratio = c.ratio,
                                   .prefetch = c.prefetch,
                                   .precompute = c.precompute,
                                   .miss_policy = c.policy});
    std::vector<std::thread> threads;
    std::atomic<int> mismatches{0};
    for (int k = 0; k < c.consumers; ++k) {
      threads.emplace_back([&, k] {
        auto reader = structure->NewReader();
        if (k == 0) mismatches += testing::CompareWithOracle(reader, oracle, Label(c));
        testing::CompareRandomAccess(reader, oracle, 17 + k, 30, Label(c));
      });
    }
    for (auto& t : threads) t.join();
    EXPECT_EQ(mismatches.load(), 0);
    for (const EngineStats& s : structure->consumer_stats()) {
      EXPECT_EQ(s.access.requests, s.access.hits + s.access.misses);
      if (c.policy == MissPolicy::kLeader) {
        EXPECT_EQ(s.consumer_relations, 0);
      }
      // The buffer holds at most its capacity, plus the block just inserted, plus blocks the
      // consumer pins (one per relation slot).
      EXPECT_LE(s.buffer_peak_blocks, structure->buffer_capacity_blocks() + 1 + kNumRelations);
    }
  }
}

std::string ConfigName(const ::testing::TestParamInfo<EveryConfiguration::ParamType>& info) {
  const auto& [prefetch, precompute, producers, consumers, ratio, policy] = info.param;
  return std::string(PrefetchName(prefetch)) + "_" + std::string(PrecomputeName(precompute)) +
         "_P" + std::to_string(producers) + "_C" + std::to_string(consumers) + "_ratio" +
         std::to_string(int(ratio * 100)) + "pct_" + std::string(MissPolicyName(policy)) + "Misses";
}

INSTANTIATE_TEST_SUITE_P(
    ActopoStructure, EveryConfiguration,
    ::testing::Combine(::testing::Values(Prefetch::kLinear, Prefetch::kSpatial,
                                         Prefetch::kAdaptive),
                       ::testing::Values(Precompute::kRequested, Precompute::kDeclared),
                       ::testing::Values(1, 2, 4),         // producers
                       ::testing::Values(1, 2),            // consumers
                       ::testing::Values(0.01, 0.2, 1.0),  // buffer ratio
                       ::testing::Values(MissPolicy::kLeader, MissPolicy::kConsumer)),
    ConfigName);

TEST(ActopoStructure, PrefetchingOffComputesOnlyWhatIsMissed) {
  auto topo = Build(testing::Lattice(6, 6, 5, 3), 8);
  testing::RelationOracle oracle(*topo);
  for (Prefetch p : {Prefetch::kLinear, Prefetch::kSpatial, Prefetch::kAdaptive}) {
    for (MissPolicy policy : {MissPolicy::kConsumer, MissPolicy::kLeader}) {
      auto structure = Create(topo, {.consumers = 1,
                                     .producers = 3,
                                     .buffer_ratio = 0.2,
                                     .prefetch = p,
                                     .miss_policy = policy});
      const std::string label =
          std::string(PrefetchName(p)) + " " + std::string(MissPolicyName(policy));
      structure->SetPrefetching(false);
      {
        auto reader = structure->NewReader();
        EXPECT_EQ(testing::CompareWithOracle(reader, oracle, label), 0);
      }
      const EngineStats off = structure->stats();
      EXPECT_EQ(off.worker_relations, 0) << label;  // workers only ever prefetch
      if (policy == MissPolicy::kConsumer) {
        EXPECT_EQ(off.leader_relations, 0) << label;
        EXPECT_EQ(off.consumer_relations, off.access.misses) << label;
      } else {
        EXPECT_EQ(off.leader_relations, off.access.misses) << label;  // served, nothing more
      }
      // Switched while a consumer reads: results stay exact.
      std::atomic<bool> done{false};
      std::thread toggler([&] {
        for (int i = 0; !done.load(); ++i) {
          structure->SetPrefetching(i % 2 == 1);
          std::this_thread::sleep_for(std::chrono::microseconds(200));
        }
      });
      {
        auto reader = structure->NewReader();
        EXPECT_EQ(testing::CompareWithOracle(reader, oracle, label + " toggled"), 0);
      }
      done = true;
      toggler.join();
    }
  }
}

TEST(ActopoStructure, OneBlockBufferManyProducers) {
  constexpr int kProducers = 8;
  auto topo = Build(testing::Lattice(7, 7, 6, 5), 6);
  testing::RelationOracle oracle(*topo);
  for (Prefetch p : {Prefetch::kLinear, Prefetch::kSpatial, Prefetch::kAdaptive}) {
    auto structure = Create(topo, {.consumers = 2,
                                   .producers = kProducers,
                                   .buffer_ratio = 0.0,
                                   .prefetch = p,
                                   .precompute = Precompute::kDeclared,
                                   .miss_policy = p == Prefetch::kSpatial ? MissPolicy::kConsumer
                                                                          : MissPolicy::kLeader});
    ASSERT_EQ(structure->buffer_capacity_blocks(), 1);
    for (auto& t : CompareOnEveryConsumer(*structure, oracle, 5, 150)) t.join();
    // What holds under any schedule (whether workers got a task before the consumers needed it
    // does not): a one-block buffer evicts, and every miss was computed by someone. Beyond the
    // one block (and the one coming in), eviction spares the blocks the consumer's reader pins
    // (one per relation slot) and those with a relation being computed (one per producer and
    // the consumer), so pins alone do not bound it.
    const EngineStats s = structure->stats();
    EXPECT_GT(s.access.evictions, 0);
    EXPECT_GE(s.leader_relations + s.worker_relations + s.consumer_relations, s.access.misses);
    for (const EngineStats& c : structure->consumer_stats()) {
      EXPECT_LE(c.buffer_peak_blocks, 2 + kNumRelations + kProducers + 1);
    }
  }
}

TEST(ActopoStructure, PrefetchTurnsMissesIntoHits) {
  // A sequential sweep with linear prefetch and one producer (the leader, which computes the
  // blocks ahead in order). The schedule is forced rather than timed: at the end of each block
  // the consumer waits until the leader has computed the next one, so every block after the
  // first is a hit whatever the machine's speed.
  auto topo = Build(testing::Lattice(16, 16, 16, 2), 64);
  auto structure =
      Create(topo, {.producers = 1, .buffer_ratio = 0.5, .prefetch = Prefetch::kLinear});
  auto reader = structure->NewReader();
  uint64_t sum = 0;
  int32_t block = topo->block_of(0, 0);
  for (SimplexId v = 0; v < topo->num_vertices(); ++v) {
    if (const int32_t next = topo->block_of(0, v); next != block) {
      // Blocks hold consecutive vertices: `next` is block + 1, the leader's next computation.
      for (int waited_ms = 0; structure->stats().leader_relations < next; ++waited_ms) {
        ASSERT_LT(waited_ms, 60'000) << "the leader never computed block " << next;
        std::this_thread::sleep_for(std::chrono::milliseconds(1));
      }
      block = next;
    }
    for (SimplexId t : reader.vertex_star(v)) {
      for (SimplexId w : reader.tetrahedron_vertices(t)) sum += w * 31 + 7;
    }
  }
  EXPECT_GT(sum, 0u);
  const EngineStats s = structure->stats();
  EXPECT_EQ(s.access.requests, topo->num_blocks());
  EXPECT_EQ(s.access.misses, 1) << "only the first block, before any prefetch";
  EXPECT_EQ(s.access.hits, topo->num_blocks() - 1);
  EXPECT_GT(s.blocks_inserted, 0);
  EXPECT_GT(s.buffer_peak_bytes, 0);
}

TEST(ActopoStructure, ShutdownWhileConsumersReadKeepsResultsExact) {
  auto topo = Build(testing::Lattice(10, 9, 9, 8), 5);
  testing::RelationOracle oracle(*topo);
  auto structure = Create(
      topo, {.consumers = 2, .producers = 3, .buffer_ratio = 0.05, .prefetch = Prefetch::kSpatial});
  std::atomic<bool> started{false};
  std::vector<std::thread> threads;
  for (int k = 0; k < 2; ++k) {
    threads.emplace_back([&, k] {
      auto reader = structure->NewReader();
      started = true;
      testing::CompareRandomAccess(reader, oracle, 70 + k, 300, "before/after shutdown");
      EXPECT_EQ(testing::CompareWithOracle(reader, oracle, "after shutdown"), 0);
    });
  }
  while (!started) std::this_thread::yield();
  structure->Shutdown();  // producers stop while consumers are mid-run, possibly mid-miss
  for (auto& t : threads) t.join();
  EXPECT_GT(structure->stats().consumer_relations, 0);
}

// The threads of this process now (Linux: one entry per thread in /proc/self/task).
int ThreadCount() {
  return int(std::distance(std::filesystem::directory_iterator("/proc/self/task"),
                           std::filesystem::directory_iterator()));
}

// count() once it is `expected`, or after 10 s (a bound on a hang, not a timing assertion).
template <class Count>
int CountOnce(Count&& count, int expected) {
  int now = count();
  for (int waited_ms = 0; now != expected && waited_ms < 10'000; ++waited_ms) {
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
    now = count();
  }
  return now;
}

// The thread count once it is `expected`: a joined thread can linger in /proc/self/task for a
// moment while the kernel finishes its exit.
int ThreadCountOnce(int expected) { return CountOnce(ThreadCount, expected); }

// The thread count once it has not changed for 50 ms (threads of earlier tests done exiting).
int SettledThreadCount() {
  int count = ThreadCount(), same_ms = 0;
  for (int waited_ms = 0; same_ms < 50 && waited_ms < 10'000; ++waited_ms) {
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
    const int now = ThreadCount();
    same_ms = now == count ? same_ms + 1 : 0;
    count = now;
  }
  return count;
}

TEST(ActopoStructure, DestroyIdleAndBusyStructures) {
  auto topo = Build(testing::Lattice(8, 8, 8, 1), 8);
  testing::RelationOracle oracle(*topo);
  const int threads_before = SettledThreadCount();
  for (int round = 0; round < 20; ++round) {
    auto structure = Create(topo, {.consumers = 2,
                                   .producers = 4,
                                   .buffer_ratio = 0.3,
                                   .prefetch = Prefetch::kLinear,
                                   .precompute = Precompute::kDeclared});
    EXPECT_EQ(ThreadCountOnce(threads_before + 2 * 4), threads_before + 2 * 4)
        << "C * P producers while alive";
    if (round % 2 == 1) {
      auto reader = structure->NewReader();
      // Producers are now busy prefetching the declared set; the answer is still exact.
      const std::span<const SimplexId> star = reader.vertex_star(round);
      EXPECT_EQ(std::vector<SimplexId>(star.begin(), star.end()),
                oracle.rows(Relation::kVT)[round]);
    }
    // Destruction joins every thread, whatever they were doing.
  }
  EXPECT_EQ(ThreadCountOnce(threads_before), threads_before);
}

// Threads of this process under SCHED_IDLE (Linux: the policy of every /proc/self/task entry).
int IdleThreadCount() {
  int idle = 0;
  for (const auto& task : std::filesystem::directory_iterator("/proc/self/task")) {
    const pid_t tid = std::stoi(task.path().filename().string());
    idle += sched_getscheduler(tid) == SCHED_IDLE;
  }
  return idle;
}

TEST(ActopoStructure, IdleProducersRunUnderSchedIdleAndStayExact) {
  auto topo = Build(testing::Lattice(9, 8, 8, 3), 6);
  testing::RelationOracle oracle(*topo);
  for (ProducerPriority priority : {ProducerPriority::kNormal, ProducerPriority::kIdle}) {
    SCOPED_TRACE(ProducerPriorityName(priority));
    auto structure = Create(topo, {.consumers = 2,
                                   .producers = 2,
                                   .buffer_ratio = 0.1,
                                   .prefetch = Prefetch::kSpatial,
                                   .producer_priority = priority});
    std::vector<std::thread> threads = CompareOnEveryConsumer(*structure, oracle, 90, 200);
    // Every producer lowers itself as it starts; the count is read once they have.
    const int expected = priority == ProducerPriority::kIdle ? 2 * 2 : 0;
    EXPECT_EQ(CountOnce(IdleThreadCount, expected), expected)
        << "producers under SCHED_IDLE; consumers keep their priority";
    for (auto& t : threads) t.join();
  }
}

// A producer at idle priority gets almost no cycles while other threads hold every core, so a
// consumer that waited on it for as long as it took would stall with it. Here the leader is held
// inside its prefetch of block 1 on purpose. At idle priority the consumer that misses block 1
// waits about one computation's time, then computes it itself and reads exact rows while the
// leader is still held; at normal priority it waits for the leader, which is let go after a while.
TEST(ActopoStructure, ConsumerComputesWhatAStalledIdleProducerHolds) {
  auto topo = Build(testing::Lattice(8, 8, 8, 1), 16);
  ASSERT_GT(topo->num_blocks(), 2);
  testing::RelationOracle oracle(*topo);
  const auto expect_star = [&](ActopoStructure::Reader& reader, int32_t block) {
    const SimplexId v = topo->block_vertex_begin(block);
    const auto star = reader.vertex_star(v);
    EXPECT_EQ(std::vector<SimplexId>(star.begin(), star.end()), oracle.rows(Relation::kVT)[v]);
  };
  for (ProducerPriority priority : {ProducerPriority::kIdle, ProducerPriority::kNormal}) {
    for (MissPolicy policy : {MissPolicy::kConsumer, MissPolicy::kLeader}) {
      SCOPED_TRACE(std::string(ProducerPriorityName(priority)) + " " +
                   std::string(MissPolicyName(policy)));
      std::promise<void> entered;
      std::atomic<bool> fired{false}, let_go{false}, read{false};
      auto structure =
          Create(topo, {.consumers = 1,
                        .producers = 1,
                        .buffer_ratio = 1.0,
                        .prefetch = Prefetch::kLinear,
                        .miss_policy = policy,
                        .producer_priority = priority,
                        .before_producer_computes = [&](int32_t block, Relation r) {
                          if (block == 1 && r == Relation::kVT && !fired.exchange(true)) {
                            entered.set_value();
                            while (!let_go) std::this_thread::yield();
                          }
                        }});
      // Whatever happens below, the leader is let go before the structure joins it.
      absl::Cleanup let_go_at_exit = [&] { let_go = true; };
      std::thread releaser;
      EngineStats before;
      {
        auto reader = structure->NewReader();
        // Block 0, computed by the consumer (kConsumer) or served by the leader (kLeader); the
        // leader then prefetches block 1 and is held there.
        expect_star(reader, 0);
        ASSERT_EQ(entered.get_future().wait_for(std::chrono::seconds(60)),
                  std::future_status::ready);
        // On a busy machine an idle leader may have been too slow for block 0 already.
        before = structure->stats();
        // Let go after 100 ms at normal priority; at idle priority once block 1 was read, or
        // after 30 s so that a consumer waiting on the leader fails the test instead of hanging.
        releaser = std::thread([&, hold = priority == ProducerPriority::kIdle
                                              ? std::chrono::milliseconds(30'000)
                                              : std::chrono::milliseconds(100)] {
          const auto until = std::chrono::steady_clock::now() + hold;
          while (!read && std::chrono::steady_clock::now() < until) {
            std::this_thread::sleep_for(std::chrono::milliseconds(1));
          }
          let_go = true;
        });
        expect_star(reader, 1);
        read = true;
      }
      releaser.join();
      const EngineStats after = structure->stats();
      const int64_t by_consumer = priority == ProducerPriority::kIdle ? 1 : 0;
      EXPECT_EQ(after.waits_abandoned - before.waits_abandoned, by_consumer);
      EXPECT_EQ(after.consumer_relations - before.consumer_relations, by_consumer)
          << "block 1 computed by the consumer at idle priority, by the leader at normal";
    }
  }
}

// What a consumer computes in (its block scratch) goes with its reader: a thread that runs
// consumers for the server's whole life (the service's executors) keeps nothing of a job.
TEST(ActopoStructure, TheConsumersThreadKeepsNoScratchOnceItsReaderIsGone) {
  // One block of ~180k tetrahedra: the scratch of its triangle relations is megabytes.
  auto topo = Build(testing::Lattice(32, 32, 32), 1 << 30);
  ASSERT_EQ(topo->num_blocks(), 1);
  const int64_t before = HeapInUseBytes();
  int64_t computed = 0;
  {
    auto structure = Create(topo, {.consumers = 1, .producers = 1});
    structure->SetPrefetching(false);  // every relation computed here, on this thread
    auto reader = structure->NewReader();
    for (Relation r : AllRelations()) EXPECT_FALSE(reader.get(r, 0).empty()) << RelationCode(r);
    computed = structure->stats().consumer_relations;
  }
  EXPECT_EQ(computed, kNumRelations - 4);  // all but EV, FV, TV and FB, which are static
  EXPECT_LT(HeapInUseBytes() - before, int64_t(1) << 20);
}

TEST(ActopoStructure, DropBufferedRelationsKeepsWhatAReaderPins) {
  auto topo = Build(testing::Lattice(8, 8, 8, 2), 16);
  testing::RelationOracle oracle(*topo);
  auto structure = Create(topo, {.consumers = 1, .producers = 2, .buffer_ratio = 0.5});
  structure->SetPrefetching(false);  // the reader's misses only: nothing comes in meanwhile
  {
    auto sweeping = structure->NewReader();
    EXPECT_EQ(testing::CompareWithOracle(sweeping, oracle, "before the drop"), 0);
  }
  EXPECT_GT(structure->stats().buffer_blocks, 1);
  auto reader = structure->NewReader();
  const SimplexId v = topo->num_vertices() / 2;
  const auto star = reader.vertex_star(v);  // pins v's block for VT
  structure->DropBufferedRelations();
  const EngineStats s = structure->stats();
  EXPECT_EQ(s.buffer_blocks, 1) << "only the block the reader pins";
  EXPECT_EQ(std::vector<SimplexId>(star.begin(), star.end()), oracle.rows(Relation::kVT)[v]);
  EXPECT_EQ(testing::CompareWithOracle(reader, oracle, "after the drop"), 0);
}

TEST(ActopoStructure, AFinishedBlockLeavesTheBufferAtOnce) {
  auto topo = Build(testing::Lattice(8, 8, 8, 2), 16);
  testing::RelationOracle oracle(*topo);
  auto structure = Create(topo, {.consumers = 1, .producers = 2, .buffer_ratio = 1.0});
  structure->SetPrefetching(false);  // the reader's misses only: nothing comes in meanwhile
  auto reader = structure->NewReader();
  for (int32_t b = 0; b < topo->num_blocks(); ++b) {
    ASSERT_EQ(testing::CompareBlockStarsAndEdges(reader, oracle, b), 0);
    reader.Finished(b);  // its pins go, then the block
    const EngineStats s = structure->stats();
    EXPECT_EQ(s.buffer_blocks, 0) << "block " << b;
    EXPECT_EQ(s.buffer_bytes, 0) << "block " << b;
  }
  const EngineStats s = structure->stats();
  EXPECT_EQ(s.buffer_peak_blocks, 1) << "a sweep holds the block it reads, none behind it";
  EXPECT_EQ(s.access.evictions, topo->num_blocks());
  // Read again, a finished block is computed again, and correct.
  EXPECT_EQ(testing::CompareWithOracle(reader, oracle, "after the sweep"), 0);
}

TEST(ActopoStructure, RejectsBadOptions) {
  struct Case {
    ActopoStructure::Options options;
    std::string message;
  };
  const Case cases[] = {
      {{.consumers = 0}, "consumers: 0 is outside [1, 64]"},
      {{.consumers = 65}, "consumers: 65 is outside [1, 64]"},
      {{.producers = 0}, "producers: 0 is outside [1, 64]"},
      {{.producers = 65}, "producers: 65 is outside [1, 64]"},
      {{.buffer_ratio = 1.5}, "buffer_ratio: 1.5 is outside [0, 1]"},
      {{.buffer_ratio = -0.1}, "buffer_ratio: -0.1 is outside [0, 1]"},
      {{.buffer_ratio = std::nan("")}, "buffer_ratio: nan is outside [0, 1]"},
  };
  auto topo = Build(testing::SingleTetrahedron(), 1);
  for (const Case& c : cases) {
    const absl::Status status = ActopoStructure::Create(topo, c.options).status();
    EXPECT_EQ(status.code(), absl::StatusCode::kInvalidArgument) << c.message;
    EXPECT_EQ(status.message(), c.message);
    EXPECT_EQ(ActopoStructure::Validate(c.options), status);
  }
  EXPECT_TRUE(
      ActopoStructure::Validate({.consumers = 64, .producers = 64, .buffer_ratio = 0}).ok());
}

}  // namespace
}  // namespace actopo
