#include "server/core/relation_buffer.h"

#include <algorithm>

namespace actopo {

RelationBuffer::RelationBuffer(int32_t num_blocks, int capacity_blocks)
    : capacity_(std::max(1, capacity_blocks)),
      cells_(size_t(num_blocks) * kNumRelations),
      is_resident_(num_blocks, 0) {}

RelationBuffer::~RelationBuffer() {
  for (Cell& c : cells_) delete c.data.load(std::memory_order_relaxed);
}

const RelationBlock* RelationBuffer::TryPin(int32_t block, Relation r) {
  Cell& c = cell(block, r);
  c.pins.fetch_add(1, std::memory_order_seq_cst);
  if (c.state.load(std::memory_order_seq_cst) == State::kReady) {
    return c.data.load(std::memory_order_acquire);
  }
  c.pins.fetch_sub(1, std::memory_order_seq_cst);
  return nullptr;
}

void RelationBuffer::Unpin(int32_t block, Relation r) {
  cell(block, r).pins.fetch_sub(1, std::memory_order_seq_cst);
}

RelationBuffer::State RelationBuffer::state(int32_t block, Relation r) const {
  return cell(block, r).state.load(std::memory_order_acquire);
}

bool RelationBuffer::StartComputing(int32_t block, Relation r) {
  State expected = State::kAbsent;
  return cell(block, r).state.compare_exchange_strong(expected, State::kComputing,
                                                      std::memory_order_acq_rel);
}

RelationBuffer::Evicted RelationBuffer::Publish(int32_t block, Relation r,
                                                std::unique_ptr<RelationBlock> data, bool pin) {
  Evicted evicted;
  MutexLock lock(mu_);
  Cell& c = cell(block, r);
  AddBytes(data->bytes());
  c.data.store(data.release(), std::memory_order_release);
  if (pin) c.pins.fetch_add(1, std::memory_order_seq_cst);
  c.state.store(State::kReady, std::memory_order_seq_cst);
  if (is_resident_[block]) return evicted;
  is_resident_[block] = 1;
  resident_.push_back(block);
  blocks_inserted_.fetch_add(1, std::memory_order_relaxed);
  Raise(peak_blocks_, int64_t(resident_.size()));
  if (int(resident_.size()) > capacity_) {
    EvictOldest(std::max<size_t>(1, resident_.size() / 2), block, evicted);
  }
  blocks_.store(int64_t(resident_.size()), std::memory_order_relaxed);
  return evicted;
}

RelationBuffer::Evicted RelationBuffer::EvictAll() {
  Evicted evicted;
  MutexLock lock(mu_);
  EvictOldest(resident_.size(), /*keep=*/-1, evicted);
  blocks_.store(int64_t(resident_.size()), std::memory_order_relaxed);
  return evicted;
}

RelationBuffer::Evicted RelationBuffer::Evict(int32_t block) {
  Evicted evicted;
  MutexLock lock(mu_);
  if (!is_resident_[block] || !TryEvictBlock(block, evicted)) return evicted;
  is_resident_[block] = 0;
  // A finished block is among the oldest: the scan from the front is short.
  resident_.erase(std::find(resident_.begin(), resident_.end(), block));
  evicted.blocks = 1;
  evictions_.fetch_add(1, std::memory_order_relaxed);
  blocks_.store(int64_t(resident_.size()), std::memory_order_relaxed);
  return evicted;
}

void RelationBuffer::EvictOldest(size_t to_evict, int32_t keep, Evicted& out) {
  std::vector<int32_t> still;
  still.reserve(resident_.size());
  for (int32_t b : resident_) {
    if (to_evict == 0 || b == keep || !TryEvictBlock(b, out)) {
      still.push_back(b);
      continue;
    }
    --to_evict;
    ++out.blocks;
    is_resident_[b] = 0;
  }
  resident_ = std::move(still);
  evictions_.fetch_add(out.blocks, std::memory_order_relaxed);
}

bool RelationBuffer::TryEvictBlock(int32_t b, Evicted& out) {
  for (Relation r : AllRelations()) {
    if (cell(b, r).state.load(std::memory_order_acquire) == State::kComputing) return false;
  }
  bool all_gone = true;
  for (Relation r : AllRelations()) {
    Cell& c = cell(b, r);
    State expected = State::kReady;
    if (!c.state.compare_exchange_strong(expected, State::kEvicting, std::memory_order_seq_cst)) {
      if (expected == State::kComputing) all_gone = false;  // started since the check above
      continue;
    }
    if (c.pins.load(std::memory_order_seq_cst) > 0) {
      c.state.store(State::kReady, std::memory_order_seq_cst);
      all_gone = false;
      continue;
    }
    std::unique_ptr<RelationBlock> data(c.data.exchange(nullptr, std::memory_order_acq_rel));
    AddBytes(-data->bytes());
    out.data.push_back(std::move(data));
    c.state.store(State::kAbsent, std::memory_order_release);
  }
  return all_gone;
}

void RelationBuffer::AddBytes(int64_t delta) {
  const int64_t now = bytes_.fetch_add(delta, std::memory_order_relaxed) + delta;
  Raise(peak_bytes_, now);
}

void RelationBuffer::Raise(std::atomic<int64_t>& peak, int64_t value) {
  int64_t seen = peak.load(std::memory_order_relaxed);
  while (value > seen && !peak.compare_exchange_weak(seen, value, std::memory_order_relaxed)) {
  }
}

RelationBuffer::Stats RelationBuffer::stats() const {
  return {.bytes = bytes_.load(std::memory_order_relaxed),
          .peak_bytes = peak_bytes_.load(std::memory_order_relaxed),
          .blocks = blocks_.load(std::memory_order_relaxed),
          .peak_blocks = peak_blocks_.load(std::memory_order_relaxed),
          .blocks_inserted = blocks_inserted_.load(std::memory_order_relaxed),
          .evictions = evictions_.load(std::memory_order_relaxed)};
}

}  // namespace actopo
