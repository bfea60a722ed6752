// The structure an algorithm runs on and how it is set up: one set of options shared by the
// service's sessions and actopo-bench, their defaults, one validator, and the structures' own
// options built from them.
//
//   StructureOptions o{.kind = StructureKind::kActopo, .buffer_ratio = 0.1};
//   o = WithDefaults(o);                        // zeros: from the machine's cores
//   RETURN_IF_ERROR(ValidateStructureOptions(o, "engine."));  // "engine.consumers: 0 is ..."
//   ASSIGN_OR_RETURN(auto engine,
//                    ActopoStructure::Create(topology, EngineOptions(o, algorithm)));
//
// Error messages name the option as spelled here (consumers, producers, buffer_ratio,
// query_readers), behind the caller's prefix (the service passes its request field path); the
// ranges are the engine's (ActopoStructure::Validate).
#ifndef ACTOPO_SERVER_ALGORITHMS_STRUCTURE_OPTIONS_H_
#define ACTOPO_SERVER_ALGORITHMS_STRUCTURE_OPTIONS_H_

#include <cstdint>
#include <optional>
#include <span>
#include <string_view>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "server/algorithms/registry.h"
#include "server/core/actopo_structure.h"
#include "server/core/compact_structure.h"
#include "server/core/parallel.h"

namespace actopo {

enum class StructureKind : uint8_t { kExplicit, kCompact, kActopo };

std::string_view StructureName(StructureKind s);  // "explicit", "compact", "actopo"
std::span<const StructureKind> AllStructures();
// The errors list what is accepted. "auto" parses to nullopt (chosen per algorithm).
absl::StatusOr<StructureKind> ParseStructure(std::string_view name);
absl::StatusOr<std::optional<Prefetch>> ParsePrefetch(std::string_view name);
absl::StatusOr<std::optional<Precompute>> ParsePrecompute(std::string_view name);
absl::StatusOr<MissPolicy> ParseMissPolicy(std::string_view name);
absl::StatusOr<std::optional<ProducerPriority>> ParseProducerPriority(std::string_view name);

// Idle when the consumers take every core: producers would otherwise take their cycles from the
// consumers (ProducerPriority, bench/RESULTS.md). Normal when cores are left for the producers.
ProducerPriority DefaultProducerPriority(int consumers, int cores);

struct StructureOptions {
  StructureKind kind = StructureKind::kActopo;
  int consumers = 0;                 // the algorithm's threads; 0: one per core
  int producers = 0;                 // actopo, per consumer (1 leader + workers); 0: one
  double buffer_ratio = 0.2;         // actopo buffer / compact cache, as a fraction of the blocks
  std::optional<Prefetch> prefetch;  // unset: DefaultPrefetch(algorithm)
  std::optional<Precompute> precompute;  // unset: DefaultPrecompute(algorithm)
  MissPolicy miss_policy = MissPolicy::kConsumer;
  std::optional<ProducerPriority> producer_priority;  // unset: DefaultProducerPriority
  int query_readers = 0;  // service: relation calls answered at once; 0: min(cores, 4)
};

inline constexpr int kMaxQueryReaders = 64;

// The zeros and the unset producer priority replaced by this machine's defaults (DefaultThreadPlan,
// DefaultProducerPriority); other fields unchanged.
StructureOptions WithDefaults(StructureOptions options, int cores = DefaultThreads());

// INVALID_ARGUMENT for the first option out of range, named behind `field_prefix`:
// consumers and producers in [1, 64], buffer_ratio in [0, 1], query_readers in [1, 64]. Call
// after WithDefaults.
absl::Status ValidateStructureOptions(const StructureOptions& options,
                                      std::string_view field_prefix = "");

// The engine that runs `algorithm` with `consumers` threads (0: options.consumers): the
// algorithm's declared relations, and its prefetch and precompute modes unless set.
ActopoStructure::Options EngineOptions(const StructureOptions& options, Algorithm algorithm,
                                       int consumers = 0);
// The engine that answers relation queries, one consumer per query reader: no declared set, so
// spatial prefetch of the requested relation unless set.
ActopoStructure::Options QueryEngineOptions(const StructureOptions& options);
// A compact structure whose caches serve `consumers` readers at once.
CompactStructure::Options CacheOptions(const StructureOptions& options, int consumers);

}  // namespace actopo

#endif  // ACTOPO_SERVER_ALGORITHMS_STRUCTURE_OPTIONS_H_
