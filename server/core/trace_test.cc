// The trace recorder writes valid trace-event JSON with named threads and a cap; the engines'
// traces account for every computation, wait and eviction their counters report.
#include "server/core/trace.h"

#include <map>
#include <sstream>
#include <thread>
#include <vector>

#include "gtest/gtest.h"
#include "nlohmann/json.hpp"
#include "server/core/actopo_structure.h"
#include "server/core/compact_structure.h"
#include "server/core/partition.h"
#include "server/core/testing/status.h"
#include "server/core/testing/test_meshes.h"

namespace actopo {
namespace {

using Json = nlohmann::json;

Json Written(const Trace& trace) {
  std::ostringstream out;
  trace.WriteJson(out);
  return Json::parse(out.str());  // throws (fails the test) on invalid JSON
}

// thread name -> tid, from the metadata events.
std::map<std::string, int> ThreadNames(const Json& json) {
  std::map<std::string, int> out;
  for (const Json& e : json["traceEvents"]) {
    if (e["ph"] == "M" && e["name"] == "thread_name") out[e["args"]["name"]] = e["tid"];
  }
  return out;
}

std::vector<Json> Events(const Json& json, const std::string& category) {
  std::vector<Json> out;
  for (const Json& e : json["traceEvents"]) {
    if (e["ph"] != "M" && e["cat"] == category) out.push_back(e);
  }
  return out;
}

TEST(Trace, SpansAndInstantsPerNamedThread) {
  Trace trace;
  std::vector<std::thread> threads;
  for (int i = 0; i < 3; ++i) {
    threads.emplace_back([&, i] {
      SetThreadRole("worker " + std::to_string(i));
      for (int k = 0; k < 100; ++k) {
        Trace::Scope span(&trace, "VT", "worker", {.block = k, .relation = "VT"});
      }
      trace.Instant("evict", "buffer", {.count = i});
    });
  }
  for (std::thread& t : threads) t.join();
  { Trace::Scope none(nullptr, "ignored", "phase"); }

  const Json json = Written(trace);
  const std::map<std::string, int> names = ThreadNames(json);
  ASSERT_EQ(names.size(), 3u);
  std::map<int, int> spans_per_tid;
  const std::vector<Json> spans = Events(json, "worker");
  ASSERT_EQ(spans.size(), 300u);
  double last_ts = -1;
  int last_tid = -1;
  for (const Json& e : spans) {
    EXPECT_EQ(e["ph"], "X");
    EXPECT_EQ(e["name"], "VT");
    EXPECT_EQ(e["args"]["relation"], "VT");
    EXPECT_GE(e["dur"].get<double>(), 0);
    if (e["tid"] == last_tid) {
      EXPECT_GE(e["ts"].get<double>(), last_ts);  // in order per thread
    }
    last_ts = e["ts"];
    last_tid = e["tid"];
    ++spans_per_tid[e["tid"]];
  }
  for (const auto& [name, tid] : names) EXPECT_EQ(spans_per_tid[tid], 100) << name;
  const std::vector<Json> instants = Events(json, "buffer");
  ASSERT_EQ(instants.size(), 3u);
  for (const Json& e : instants) EXPECT_EQ(e["ph"], "i");
  EXPECT_EQ(json["otherData"]["events"], 303);
  EXPECT_EQ(json["otherData"]["dropped"], 0);
  EXPECT_EQ(trace.events(), 303);
}

TEST(Trace, KeepsAtMostMaxEventsAndCountsTheRest) {
  Trace trace(/*max_events=*/10);
  SetThreadRole("a \"quoted\"\n role");
  for (int k = 0; k < 25; ++k) trace.Instant("tick", "test");
  EXPECT_EQ(trace.events(), 10);
  EXPECT_EQ(trace.dropped(), 15);
  const Json json = Written(trace);
  EXPECT_EQ(Events(json, "test").size(), 10u);
  EXPECT_EQ(json["otherData"]["dropped"], 15);
  EXPECT_EQ(ThreadNames(json).count("a \"quoted\"\n role"), 1u);
  SetThreadRole("");
}

std::shared_ptr<const Topology> Lattice() {
  const Mesh mesh = testing::Lattice(6, 6, 5, 3);
  return OkValue(Topology::Build(mesh, OctreeBlocks(mesh.points, {.bucket_capacity = 12})));
}

// Sweeps VT and ET over every vertex and edge.
template <class Reader>
void Sweep(Reader& reader) {
  const Topology& topo = reader.topology();
  for (SimplexId v = 0; v < topo.num_vertices(); ++v) reader.vertex_star(v);
  for (SimplexId e = 0; e < topo.num_edges(); ++e) reader.edge_star(e);
}

int64_t SumCounts(const std::vector<Json>& events) {
  int64_t n = 0;
  for (const Json& e : events) n += e["args"]["count"].get<int64_t>();
  return n;
}

TEST(Trace, ActopoEngineEventsMatchItsCounters) {
  for (MissPolicy policy : {MissPolicy::kLeader, MissPolicy::kConsumer}) {
    auto structure = OkValue(ActopoStructure::Create(
        Lattice(), {.consumers = 1, .producers = 3, .buffer_ratio = 0.1, .miss_policy = policy}));
    auto trace = std::make_shared<Trace>();
    structure->SetTrace(trace);
    {
      SetThreadRole("consumer 0");
      auto reader = structure->NewReader();
      Sweep(reader);
    }
    structure->Shutdown();  // every producer has finished its last computation
    structure->SetTrace(nullptr);
    const EngineStats stats = structure->stats();
    const Json json = Written(*trace);

    const std::map<std::string, int> names = ThreadNames(json);
    EXPECT_EQ(names.count("consumer 0"), 1u);
    // A thread gets a row with its first event; a leader may have computed nothing.
    EXPECT_EQ(names.count("leader 0"), stats.leader_relations > 0 ? 1u : 0u);
    const std::vector<Json> leader = Events(json, "leader"), worker = Events(json, "worker"),
                            consumer = Events(json, "consumer");
    int64_t consumer_computes = 0, waits = 0;
    for (const Json& e : consumer) (e["name"] == "wait" ? waits : consumer_computes) += 1;
    EXPECT_EQ(int64_t(leader.size()), stats.leader_relations);
    EXPECT_EQ(int64_t(worker.size()), stats.worker_relations);
    EXPECT_EQ(consumer_computes, stats.consumer_relations);
    EXPECT_EQ(waits, stats.access.misses);
    EXPECT_GT(stats.access.misses, 0);
    EXPECT_EQ(SumCounts(Events(json, "buffer")), stats.access.evictions);
    EXPECT_GT(stats.access.evictions, 0);
    for (const Json& e : leader) {
      EXPECT_TRUE(e["name"] == "VT" || e["name"] == "ET") << e;
      EXPECT_GE(e["args"]["block"].get<int>(), 0);
      EXPECT_EQ(e["tid"], names.at("leader 0"));
    }
    std::map<int, std::string> row;  // tid -> thread name
    for (const auto& [name, tid] : names) row[tid] = name;
    for (const Json& e : worker) {
      const std::string name = row[e["tid"].get<int>()];
      EXPECT_TRUE(name == "worker 0.1" || name == "worker 0.2") << name;
    }
  }
  SetThreadRole("");
}

TEST(Trace, CompactReadersRecordTheirComputationsAndEvictions) {
  CompactStructure structure(Lattice(), {.cache_ratio = 0.1, .consumers = 1});
  auto trace = std::make_shared<Trace>();
  structure.SetTrace(trace);
  {
    auto reader = structure.NewReader();
    Sweep(reader);
  }
  structure.SetTrace(nullptr);
  {
    auto untraced = structure.NewReader();
    Sweep(untraced);
  }
  const AccessStats all = structure.stats();
  const Json json = Written(*trace);
  const int64_t computes = int64_t(Events(json, "consumer").size());
  EXPECT_GT(computes, 0);
  EXPECT_EQ(2 * computes, all.relations_computed);  // the same sweep twice, one traced
  EXPECT_EQ(2 * SumCounts(Events(json, "buffer")), all.evictions);
}

}  // namespace
}  // namespace actopo
