#include "server/algorithms/topo_relations.h"

#include <cstdio>
#include <mutex>

#include "server/core/actopo_structure.h"
#include "server/core/compact_structure.h"
#include "server/core/explicit_structure.h"
#include "server/core/structures.h"

namespace actopo {
namespace {

using R = Relation;
// TTK's 20 first: the default sweep is the first kTtkSweeps.
constexpr int kTtkSweeps = 20;
constexpr std::array<Relation, kNumRelations> kSweeps = {
    R::kVT, R::kEV, R::kET, R::kFV, R::kFT, R::kTV, R::kVE, R::kVF, R::kEF, R::kFE, R::kTE,
    R::kTF, R::kVV, R::kTT, R::kVL, R::kEL, R::kFL, R::kVB, R::kEB, R::kFB, R::kEE, R::kFF};

// splitmix64's finaliser: a cheap, well-mixing 64-bit hash.
inline uint64_t Mix(uint64_t x) {
  x ^= x >> 30;
  x *= 0xbf58476d1ce4e5b9ULL;
  x ^= x >> 27;
  x *= 0x94d049bb133111ebULL;
  return x ^ (x >> 31);
}

struct Partial {
  std::array<int64_t, kNumRelations> totals{};
  uint64_t checksum = 0;
};

template <Relation Rel, class Reader>
void SweepBlock(Reader& reader, int32_t block, Partial& out) {
  const Topology& topo = reader.topology();
  constexpr int dim = SourceDimension(Rel);
  const SimplexId end = topo.block_begin(dim, block + 1);
  int64_t total = 0;
  uint64_t checksum = 0;
  for (SimplexId s = topo.block_begin(dim, block); s < end; ++s) {
    const auto row = reader.template get<Rel>(s);
    uint64_t h = uint64_t(Index(Rel)) << 56 ^ uint64_t(s);
    for (SimplexId x : row) h = (h ^ uint64_t(x)) * 0x100000001b3ULL;  // order-sensitive
    checksum += Mix(h ^ row.size());
    total += static_cast<int64_t>(row.size());
  }
  out.totals[Index(Rel)] += total;
  out.checksum += checksum;
}

template <class Reader, size_t... I>
void SweepBlockDispatch(Relation r, Reader& reader, int32_t block, Partial& out,
                        std::index_sequence<I...>) {
  // One compile-time instantiation per relation; selected once per (sweep, block).
  ((r == static_cast<Relation>(I) ? SweepBlock<static_cast<Relation>(I)>(reader, block, out)
                                  : void()),
   ...);
}

}  // namespace

std::string TopoRelationsResult::checksum_hex() const {
  char buf[17];
  std::snprintf(buf, sizeof buf, "%016llx", static_cast<unsigned long long>(checksum));
  return buf;
}

std::span<const Relation> TopoRelationsSweeps(bool all) {
  return std::span<const Relation>(kSweeps).first(all ? kSweeps.size() : kTtkSweeps);
}

// An explicit structure composes the edge and triangle neighbours from the others as they are
// read (explicit_structure.h), so they need not be stored.
RelationSet TopoRelationsDeclared() { return ExplicitStructure::DefaultRelations(); }

template <TopologicalStructure Structure>
absl::StatusOr<TopoRelationsResult> RunTopoRelations(Structure& structure,
                                                     const RunContext& context,
                                                     TopoRelationsOptions options) {
  const Topology& topo = structure.topology();
  const std::span<const Relation> sweeps = TopoRelationsSweeps(options.all);
  std::mutex mu;
  TopoRelationsResult result{.all = options.all};
  const absl::Status status = RunOnConsumers(
      context, topo, int64_t(sweeps.size()) * topo.num_blocks(),
      [&](int, BlockRange range, WorkTracker& tracker) {
        auto reader = structure.NewReader();
        Partial partial;
        for (Relation r : sweeps) {
          for (int32_t b = range.begin; b < range.end; ++b) {
            SweepBlockDispatch(r, reader, b, partial, std::make_index_sequence<kNumRelations>());
            if (!tracker.Done()) return;
          }
        }
        std::lock_guard<std::mutex> lock(mu);
        for (int i = 0; i < kNumRelations; ++i) result.totals[i] += partial.totals[i];
        result.checksum += partial.checksum;
      });
  if (!status.ok()) return status;
  return result;
}

#define ACTOPO_INSTANTIATE(S)                                                          \
  template absl::StatusOr<TopoRelationsResult> RunTopoRelations(S&, const RunContext&, \
                                                                TopoRelationsOptions);
ACTOPO_FOR_EACH_STRUCTURE(ACTOPO_INSTANTIATE)
#undef ACTOPO_INSTANTIATE

}  // namespace actopo
