// The options sessions and actopo-bench share: names, defaults, the validator's messages, and
// the structures' options built from them.
#include "server/algorithms/structure_options.h"

#include <cmath>
#include <string>

#include "gmock/gmock.h"
#include "gtest/gtest.h"
#include "server/core/testing/status.h"

namespace actopo {
namespace {

TEST(StructureOptions, NamesRoundTrip) {
  for (StructureKind s : AllStructures()) EXPECT_EQ(OkValue(ParseStructure(StructureName(s))), s);
  for (Prefetch p : {Prefetch::kLinear, Prefetch::kSpatial, Prefetch::kAdaptive}) {
    EXPECT_EQ(OkValue(ParsePrefetch(PrefetchName(p))), p);
  }
  for (Precompute p : {Precompute::kRequested, Precompute::kDeclared}) {
    EXPECT_EQ(OkValue(ParsePrecompute(PrecomputeName(p))), p);
  }
  for (MissPolicy p : {MissPolicy::kLeader, MissPolicy::kConsumer}) {
    EXPECT_EQ(OkValue(ParseMissPolicy(MissPolicyName(p))), p);
  }
  for (ProducerPriority p : {ProducerPriority::kNormal, ProducerPriority::kIdle}) {
    EXPECT_EQ(OkValue(ParseProducerPriority(ProducerPriorityName(p))), p);
  }
  EXPECT_EQ(OkValue(ParseProducerPriority("auto")), std::nullopt);
  EXPECT_EQ(OkValue(ParsePrefetch("auto")), std::nullopt);
  EXPECT_EQ(OkValue(ParsePrecompute("auto")), std::nullopt);
}

TEST(StructureOptions, UnknownNamesListWhatIsAccepted) {
  struct Case {
    absl::Status status;
    std::string message;
  };
  const Case cases[] = {
      {ParseStructure("octree").status(),
       "unknown structure 'octree'; available: explicit, compact, actopo"},
      {ParsePrefetch("random").status(),
       "unknown prefetch mode 'random'; available: auto, linear, spatial, adaptive"},
      {ParsePrecompute("all").status(),
       "unknown precompute scope 'all'; available: auto, requested, declared"},
      {ParseMissPolicy("worker").status(),
       "unknown miss policy 'worker'; available: leader, consumer"},
      {ParseProducerPriority("high").status(),
       "unknown producer priority 'high'; available: auto, normal, idle"},
  };
  for (const Case& c : cases) {
    EXPECT_EQ(c.status.code(), absl::StatusCode::kInvalidArgument) << c.message;
    EXPECT_EQ(c.status.message(), c.message);
  }
}

TEST(StructureOptions, ZerosComeFromTheCores) {
  const StructureOptions actopo = WithDefaults({.kind = StructureKind::kActopo}, 8);
  EXPECT_EQ(actopo.consumers, 8);
  EXPECT_EQ(actopo.producers, 1);
  EXPECT_EQ(actopo.query_readers, 4);
  const StructureOptions compact = WithDefaults({.kind = StructureKind::kCompact}, 2);
  EXPECT_EQ(compact.consumers, 2);
  EXPECT_EQ(compact.producers, 1);
  EXPECT_EQ(compact.query_readers, 2);
  const StructureOptions set =
      WithDefaults({.consumers = 3, .producers = 5, .buffer_ratio = 0.5, .query_readers = 7}, 8);
  EXPECT_EQ(set.consumers, 3);
  EXPECT_EQ(set.producers, 5);
  EXPECT_EQ(set.buffer_ratio, 0.5);
  EXPECT_EQ(set.query_readers, 7);
}

TEST(StructureOptions, ProducersIdleWhenTheConsumersTakeEveryCore) {
  EXPECT_EQ(WithDefaults({.kind = StructureKind::kActopo}, 2).producer_priority,
            ProducerPriority::kIdle);
  EXPECT_EQ(WithDefaults({.kind = StructureKind::kActopo, .consumers = 1}, 2).producer_priority,
            ProducerPriority::kNormal);
  EXPECT_EQ(WithDefaults({.kind = StructureKind::kActopo, .consumers = 6}, 16).producer_priority,
            ProducerPriority::kNormal);
  EXPECT_EQ(WithDefaults(
                {.kind = StructureKind::kActopo, .producer_priority = ProducerPriority::kNormal}, 2)
                .producer_priority,
            ProducerPriority::kNormal);
  StructureOptions idle = WithDefaults({.kind = StructureKind::kActopo}, 4);
  EXPECT_EQ(EngineOptions(idle, Algorithm::kCriticalPoints).producer_priority,
            ProducerPriority::kIdle);
  EXPECT_EQ(QueryEngineOptions(idle).producer_priority, ProducerPriority::kIdle);
}

TEST(StructureOptions, ValidatorNamesTheOptionBehindThePrefix) {
  struct Case {
    StructureOptions options;
    std::string message;  // without prefix
  };
  const StructureOptions good = WithDefaults({}, 2);
  auto with = [&](auto change) {
    StructureOptions o = good;
    change(o);
    return o;
  };
  const Case cases[] = {
      {with([](auto& o) { o.consumers = 0; }), "consumers: 0 is outside [1, 64]"},
      {with([](auto& o) { o.consumers = 65; }), "consumers: 65 is outside [1, 64]"},
      {with([](auto& o) { o.producers = 65; }), "producers: 65 is outside [1, 64]"},
      {with([](auto& o) { o.buffer_ratio = 2; }), "buffer_ratio: 2 is outside [0, 1]"},
      {with([](auto& o) { o.buffer_ratio = std::nan(""); }), "buffer_ratio: nan is outside [0, 1]"},
      {with([](auto& o) { o.query_readers = 0; }), "query_readers: 0 is outside [1, 64]"},
      {with([](auto& o) { o.query_readers = 65; }), "query_readers: 65 is outside [1, 64]"},
  };
  EXPECT_TRUE(ValidateStructureOptions(good, "engine.").ok());
  for (const Case& c : cases) {
    const absl::Status plain = ValidateStructureOptions(c.options);
    EXPECT_EQ(plain.code(), absl::StatusCode::kInvalidArgument) << c.message;
    EXPECT_EQ(plain.message(), c.message);
    EXPECT_EQ(ValidateStructureOptions(c.options, "engine.").message(), "engine." + c.message);
  }
}

TEST(StructureOptions, EngineTakesTheAlgorithmsChoicesUnlessSet) {
  const StructureOptions o = WithDefaults({.consumers = 2, .producers = 3}, 2);
  for (Algorithm a : AllAlgorithms()) {
    const ActopoStructure::Options e = EngineOptions(o, a);
    EXPECT_EQ(e.consumers, 2);
    EXPECT_EQ(e.producers, 3);
    EXPECT_EQ(e.prefetch, DefaultPrefetch(a));
    EXPECT_EQ(e.precompute, DefaultPrecompute(a));
    // Producers compute only what the algorithm declared, and all of it but critical points'
    // VB and the simplification's and the trees' VV.
    EXPECT_EQ(e.declared | DeclaredRelations(a), DeclaredRelations(a));
    RelationSet swept = DeclaredRelations(a);
    if (a == Algorithm::kCriticalPoints) swept.Remove(Relation::kVB);
    if (a == Algorithm::kTopologicalSimplification || a == Algorithm::kMergeTree ||
        a == Algorithm::kContourTree) {
      swept.Remove(Relation::kVV);
    }
    EXPECT_EQ(e.declared, swept);
    EXPECT_TRUE(ActopoStructure::Validate(e).ok());
  }
  StructureOptions set = o;
  set.prefetch = Prefetch::kAdaptive;
  set.precompute = Precompute::kDeclared;
  set.miss_policy = MissPolicy::kLeader;
  const ActopoStructure::Options e = EngineOptions(set, Algorithm::kMorseSmale, /*consumers=*/1);
  EXPECT_EQ(e.consumers, 1);
  EXPECT_EQ(e.prefetch, Prefetch::kAdaptive);
  EXPECT_EQ(e.precompute, Precompute::kDeclared);
  EXPECT_EQ(e.miss_policy, MissPolicy::kLeader);
}

TEST(StructureOptions, QueryEngineHasAConsumerPerReader) {
  const StructureOptions o = WithDefaults({.producers = 2, .query_readers = 3}, 2);
  const ActopoStructure::Options q = QueryEngineOptions(o);
  EXPECT_EQ(q.consumers, 3);
  EXPECT_EQ(q.producers, 2);
  EXPECT_EQ(q.prefetch, Prefetch::kSpatial);
  EXPECT_EQ(q.precompute, Precompute::kRequested);
  const CompactStructure::Options c = CacheOptions(o, o.query_readers);
  EXPECT_EQ(c.consumers, 3);
  EXPECT_EQ(c.cache_ratio, o.buffer_ratio);
}

}  // namespace
}  // namespace actopo
