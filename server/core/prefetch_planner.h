// What an ACTOPO consumer's producers compute next: the blocks ahead of the block the consumer
// moved to, and which relations of them.
//
//   PrefetchPlanner planner(topology, {.prefetch = Prefetch::kSpatial, .window = 8});
//   PrefetchPlanner::Plan plan;
//   planner.Make({.block = b, .relation = Relation::kVT}, /*predicted=*/{}, needed, plan);
//   // plan.tasks: (block, relation) pairs in the order producers should take them;
//   // plan.trigger_block: re-plan when the consumer reaches this block.
//
// Pure: no threads, no locks. The engine (actopo_structure.cc) plans under its consumer's mutex;
// the TransitionModel that feeds the adaptive mode belongs to the consumer thread alone.
#ifndef ACTOPO_SERVER_CORE_PREFETCH_PLANNER_H_
#define ACTOPO_SERVER_CORE_PREFETCH_PLANNER_H_

#include <algorithm>
#include <array>
#include <cstdint>
#include <span>
#include <string_view>
#include <vector>

#include "absl/functional/function_ref.h"
#include "server/core/relation.h"
#include "server/core/topology.h"

namespace actopo {

// Which blocks producers compute ahead of the consumer.
enum class Prefetch : uint8_t {
  kLinear,    // b + 1, b + 2, ...
  kSpatial,   // blocks sharing a tetrahedron with b, ascending
  kAdaptive,  // the blocks this consumer has most often moved to from b (learned online), then
              // spatial neighbours for the rest of the window
};

// Which relations producers compute for a prefetched block.
enum class Precompute : uint8_t {
  kRequested,  // the relation the consumer last asked for
  kDeclared,   // every relation of the algorithm's declared set
};

std::string_view PrefetchName(Prefetch p);
std::string_view PrecomputeName(Precompute p);

// One (block, relation) for a producer to compute.
struct BlockTask {
  int32_t block = -1;
  Relation relation = Relation::kVV;
};

// Online model of one consumer's block-to-block moves: for each block, the four successors seen
// most often (space-saving counts), so prefetching can follow where the algorithm usually goes.
class TransitionModel {
 public:
  explicit TransitionModel(int32_t blocks) : successors_(blocks) {}

  // The consumer moved from `from` (-1: nowhere yet) to `to`.
  void Learn(int32_t from, int32_t to);

  // Up to `limit` distinct blocks other than b: b's likely successors, strongest first, then the
  // chain of strongest successors from the best one.
  void Predict(int32_t b, size_t limit, std::vector<int32_t>& out) const;

 private:
  static constexpr int kWays = 4;
  struct Entry {
    int32_t block = -1;
    int32_t count = 0;
  };
  std::vector<std::array<Entry, kWays>> successors_;
};

class PrefetchPlanner {
 public:
  struct Options {
    Prefetch prefetch = Prefetch::kLinear;
    Precompute precompute = Precompute::kRequested;
    // Relations computed per block under Precompute::kDeclared (static ones are dropped).
    RelationSet declared = RelationSet::All();
    int window = 1;  // blocks planned ahead per re-plan, at least 1
  };

  struct Plan {
    std::vector<BlockTask> tasks;
    int32_t trigger_block = -1;  // -1: no block planned, nothing to re-plan on
  };

  PrefetchPlanner(const Topology& topology, const Options& options);

  // Plans from the consumer's move to (from.block, from.relation):
  // - blocks: linear b+1..b+window (clipped at the last block); spatial b's neighbours
  //   (ascending, at most window); adaptive `predicted` first, then spatial neighbours not
  //   already listed, up to window;
  // - relations: kRequested from.relation on each planned block; kDeclared the declared set on
  //   from.block itself, then on each planned block;
  // - only pairs `needed(block, relation)` accepts (the engine skips computing or ready ones);
  // - trigger: the middle block of a linear window, the first block of a spatial or adaptive one.
  void Make(BlockTask from, std::span<const int32_t> predicted,
            absl::FunctionRef<bool(int32_t, Relation)> needed, Plan& out) const;

  // Whether the consumer's reads of `r` say where its sweep goes, so that a miss or a trigger
  // on `r` should re-plan: every relation under kRequested; under kDeclared the relations it
  // plans. Critical points sweeps VT block by block and reads VB of boundary vertices'
  // neighbours, in whatever blocks they lie: a plan from there computes blocks nobody reads.
  bool Follows(Relation r) const {
    return options_.precompute != Precompute::kDeclared ||
           std::find(declared_.begin(), declared_.end(), r) != declared_.end();
  }

  const Options& options() const { return options_; }

 private:
  const Topology& topology_;
  const Options options_;
  std::vector<Relation> declared_;  // non-static relations of options_.declared, in order
};

}  // namespace actopo

#endif  // ACTOPO_SERVER_CORE_PREFETCH_PLANNER_H_
