#include "server/core/prefetch_planner.h"

#include <algorithm>

namespace actopo {

std::string_view PrefetchName(Prefetch p) {
  switch (p) {
    case Prefetch::kLinear: return "linear";
    case Prefetch::kSpatial: return "spatial";
    case Prefetch::kAdaptive: return "adaptive";
  }
  return "?";
}

std::string_view PrecomputeName(Precompute p) {
  return p == Precompute::kRequested ? "requested" : "declared";
}

void TransitionModel::Learn(int32_t from, int32_t to) {
  if (from < 0 || from == to) return;
  Entry* slots = successors_[from].data();
  Entry* weakest = &slots[0];
  for (int i = 0; i < kWays; ++i) {
    if (slots[i].block == to) {
      ++slots[i].count;
      return;
    }
    if (slots[i].count < weakest->count) weakest = &slots[i];
  }
  weakest->block = to;
  ++weakest->count;  // space-saving: the newcomer inherits the evicted count
}

void TransitionModel::Predict(int32_t b, size_t limit, std::vector<int32_t>& out) const {
  out.clear();
  auto add = [&](int32_t block) {
    if (block >= 0 && block != b && out.size() < limit &&
        std::find(out.begin(), out.end(), block) == out.end()) {
      out.push_back(block);
    }
  };
  std::array<Entry, kWays> ranked = successors_[b];
  std::sort(ranked.begin(), ranked.end(),
            [](const Entry& x, const Entry& y) { return x.count > y.count; });
  for (const Entry& e : ranked) {
    if (e.count > 0) add(e.block);
  }
  int32_t current = ranked[0].count > 0 ? ranked[0].block : -1;
  for (size_t step = 0; current >= 0 && step < limit; ++step) {
    const Entry* best = nullptr;
    for (const Entry& e : successors_[current]) {
      if (e.count > 0 && (best == nullptr || e.count > best->count)) best = &e;
    }
    if (best == nullptr) break;
    add(best->block);
    current = best->block;
  }
}

PrefetchPlanner::PrefetchPlanner(const Topology& topology, const Options& options)
    : topology_(topology), options_(options) {
  for (Relation r : AllRelations()) {
    if (options.declared.Contains(r) && !IsStatic(r)) declared_.push_back(r);
  }
}

void PrefetchPlanner::Make(BlockTask from, std::span<const int32_t> predicted,
                           absl::FunctionRef<bool(int32_t, Relation)> needed, Plan& out) const {
  const int32_t window = std::max(1, options_.window);
  std::vector<int32_t> blocks;
  switch (options_.prefetch) {
    case Prefetch::kLinear:
      for (int32_t d = 1; d <= window && from.block + d < topology_.num_blocks(); ++d) {
        blocks.push_back(from.block + d);
      }
      break;
    case Prefetch::kAdaptive:
      for (int32_t b : predicted) {
        if (int32_t(blocks.size()) >= window) break;
        if (b != from.block && std::find(blocks.begin(), blocks.end(), b) == blocks.end()) {
          blocks.push_back(b);
        }
      }
      [[fallthrough]];
    case Prefetch::kSpatial:
      for (int32_t n : topology_.block_neighbors(from.block)) {
        if (int32_t(blocks.size()) >= window) break;
        if (std::find(blocks.begin(), blocks.end(), n) == blocks.end()) blocks.push_back(n);
      }
      break;
  }

  out.tasks.clear();
  auto add = [&](int32_t b, Relation r) {
    if (needed(b, r)) out.tasks.push_back({b, r});
  };
  if (options_.precompute == Precompute::kDeclared) {
    for (Relation r : declared_) add(from.block, r);
    for (int32_t b : blocks) {
      for (Relation r : declared_) add(b, r);
    }
  } else {
    for (int32_t b : blocks) add(b, from.relation);
  }

  // Re-plan when the consumer reaches the middle of a linear window (the rest is still ahead of
  // it), or the first, most likely block of a spatial or learned one.
  out.trigger_block = -1;
  if (!blocks.empty()) {
    out.trigger_block =
        options_.prefetch == Prefetch::kLinear ? blocks[blocks.size() / 2] : blocks.front();
  }
}

}  // namespace actopo
