#include "server/algorithms/structure_options.h"

#include <algorithm>
#include <array>
#include <string>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"

namespace actopo {
namespace {

constexpr std::array<StructureKind, 3> kStructures = {
    StructureKind::kExplicit, StructureKind::kCompact, StructureKind::kActopo};
constexpr std::array<Prefetch, 3> kPrefetches = {Prefetch::kLinear, Prefetch::kSpatial,
                                                 Prefetch::kAdaptive};
constexpr std::array<Precompute, 2> kPrecomputes = {Precompute::kRequested, Precompute::kDeclared};
constexpr std::array<MissPolicy, 2> kMissPolicies = {MissPolicy::kLeader, MissPolicy::kConsumer};
constexpr std::array<ProducerPriority, 2> kProducerPriorities = {ProducerPriority::kNormal,
                                                                 ProducerPriority::kIdle};

// The value of `values` whose name(value) is `name`; else INVALID_ARGUMENT listing them.
template <class T, size_t N, class NameFn>
absl::StatusOr<T> ParseNamed(std::string_view what, std::string_view name,
                             const std::array<T, N>& values, NameFn name_of,
                             std::string_view extra = "") {
  std::vector<std::string> names;
  if (!extra.empty()) names.emplace_back(extra);
  for (T v : values) {
    if (name_of(v) == name) return v;
    names.emplace_back(name_of(v));
  }
  return absl::InvalidArgumentError(absl::StrCat("unknown ", std::string(what), " '",
                                                 std::string(name),
                                                 "'; available: ", absl::StrJoin(names, ", ")));
}

}  // namespace

std::string_view StructureName(StructureKind s) {
  switch (s) {
    case StructureKind::kExplicit: return "explicit";
    case StructureKind::kCompact: return "compact";
    case StructureKind::kActopo: return "actopo";
  }
  return "?";
}

std::span<const StructureKind> AllStructures() { return kStructures; }

absl::StatusOr<StructureKind> ParseStructure(std::string_view name) {
  return ParseNamed("structure", name, kStructures, StructureName);
}

absl::StatusOr<std::optional<Prefetch>> ParsePrefetch(std::string_view name) {
  if (name == "auto") return std::nullopt;
  return ParseNamed("prefetch mode", name, kPrefetches, PrefetchName, "auto");
}

absl::StatusOr<std::optional<Precompute>> ParsePrecompute(std::string_view name) {
  if (name == "auto") return std::nullopt;
  return ParseNamed("precompute scope", name, kPrecomputes, PrecomputeName, "auto");
}

absl::StatusOr<MissPolicy> ParseMissPolicy(std::string_view name) {
  return ParseNamed("miss policy", name, kMissPolicies, MissPolicyName);
}

absl::StatusOr<std::optional<ProducerPriority>> ParseProducerPriority(std::string_view name) {
  if (name == "auto") return std::nullopt;
  return ParseNamed("producer priority", name, kProducerPriorities, ProducerPriorityName, "auto");
}

ProducerPriority DefaultProducerPriority(int consumers, int cores) {
  return consumers >= cores ? ProducerPriority::kIdle : ProducerPriority::kNormal;
}

StructureOptions WithDefaults(StructureOptions options, int cores) {
  const ThreadPlan plan = DefaultThreadPlan(options.kind == StructureKind::kActopo, cores);
  if (options.consumers == 0) options.consumers = plan.consumers;
  if (options.producers == 0) options.producers = std::max(plan.producers, 1);
  if (!options.producer_priority) {
    options.producer_priority = DefaultProducerPriority(options.consumers, cores);
  }
  if (options.query_readers == 0) options.query_readers = std::clamp(cores, 1, 4);
  return options;
}

absl::Status ValidateStructureOptions(const StructureOptions& options,
                                      std::string_view field_prefix) {
  // The engine's ranges apply to every structure: consumers are the algorithm's threads in
  // all three, and the buffer ratio sizes the compact cache too.
  absl::Status status = ActopoStructure::Validate({.consumers = options.consumers,
                                                   .producers = options.producers,
                                                   .buffer_ratio = options.buffer_ratio});
  if (status.ok() && (options.query_readers < 1 || options.query_readers > kMaxQueryReaders)) {
    status = absl::InvalidArgumentError(absl::StrCat("query_readers: ", options.query_readers,
                                                     " is outside [1, ", kMaxQueryReaders, "]"));
  }
  if (status.ok() || field_prefix.empty()) return status;
  return absl::Status(status.code(), absl::StrCat(std::string(field_prefix), status.message()));
}

ActopoStructure::Options EngineOptions(const StructureOptions& options, Algorithm algorithm,
                                       int consumers) {
  return {.consumers = consumers > 0 ? consumers : options.consumers,
          .producers = options.producers,
          .buffer_ratio = options.buffer_ratio,
          .prefetch = options.prefetch.value_or(DefaultPrefetch(algorithm)),
          .precompute = options.precompute.value_or(DefaultPrecompute(algorithm)),
          .declared = SweptRelations(algorithm),
          .miss_policy = options.miss_policy,
          .producer_priority = options.producer_priority.value_or(ProducerPriority::kNormal)};
}

ActopoStructure::Options QueryEngineOptions(const StructureOptions& options) {
  // Queries arrive in no order a linear sweep would follow; neighbours of the block asked for
  // are the best guess of what comes next.
  return {.consumers = options.query_readers,
          .producers = options.producers,
          .buffer_ratio = options.buffer_ratio,
          .prefetch = options.prefetch.value_or(Prefetch::kSpatial),
          .precompute = Precompute::kRequested,
          .miss_policy = options.miss_policy,
          .producer_priority = options.producer_priority.value_or(ProducerPriority::kNormal)};
}

CompactStructure::Options CacheOptions(const StructureOptions& options, int consumers) {
  return {.cache_ratio = options.buffer_ratio, .consumers = consumers};
}

}  // namespace actopo
