#include "server/core/compact_structure.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <utility>

namespace actopo {

CompactStructure::CompactStructure(std::shared_ptr<const Topology> topology, const Options& options)
    : topology_(std::move(topology)) {
  const int consumers = std::max(options.consumers, 1);
  capacity_ = static_cast<int>(std::floor(std::max(options.cache_ratio, 0.0) *
                                          topology_->num_blocks() / consumers)) +
              1;
}

void CompactStructure::SetTrace(std::shared_ptr<Trace> trace) {
  MutexLock lock(mu_);
  trace_ = std::move(trace);
}

AccessStats CompactStructure::stats() const {
  MutexLock lock(mu_);
  return finished_;
}

MemoryStats CompactStructure::memory() const {
  MemoryStats m;
  m.static_bytes = topology_->bytes().total();
  m.relation_bytes = bytes_.load();
  m.relation_peak_bytes = peak_bytes_.load();
  return m;
}

CompactStructure::Reader::Reader(CompactStructure* owner)
    : BlockSlotReader<Reader, Slot>(owner->topology_.get(), {}),
      owner_(owner),
      capacity_(owner->capacity_),
      entry_of_block_(owner->topology_->num_blocks(), -1) {
  entries_.reserve(capacity_ + kNumRelations);
  MutexLock lock(owner->mu_);
  trace_ = owner->trace_;
}

CompactStructure::Reader::Reader(Reader&& other) noexcept
    : BlockSlotReader<Reader, Slot>(other.topology_, other.slots_),
      owner_(std::exchange(other.owner_, nullptr)),
      capacity_(other.capacity_),
      entries_(std::move(other.entries_)),
      entry_of_block_(std::move(other.entry_of_block_)),
      next_insert_(other.next_insert_),
      bytes_(std::exchange(other.bytes_, 0)),
      scratch_(std::move(other.scratch_)),
      stats_(std::exchange(other.stats_, {})),
      trace_(std::move(other.trace_)) {}

CompactStructure::Reader::~Reader() {
  if (owner_ == nullptr) return;
  AddBytes(-bytes_);
  MutexLock lock(owner_->mu_);
  owner_->finished_ += stats_;
}

void CompactStructure::Reader::AddBytes(int64_t delta) {
  bytes_ += delta;
  const int64_t now = owner_->bytes_.fetch_add(delta, std::memory_order_relaxed) + delta;
  int64_t peak = owner_->peak_bytes_.load(std::memory_order_relaxed);
  while (now > peak && !owner_->peak_bytes_.compare_exchange_weak(peak, now)) {
  }
}

int CompactStructure::Reader::FindOrInsert(int32_t block) {
  if (entry_of_block_[block] >= 0) return entry_of_block_[block];
  int victim = -1;
  if (static_cast<int>(entries_.size()) >= capacity_) {
    // Oldest unpinned entry; the cache is small, a scan is cheaper than bookkeeping.
    for (int i = 0; i < static_cast<int>(entries_.size()); ++i) {
      const Entry& e = entries_[i];
      if (e.pins == 0 && (victim < 0 || e.inserted < entries_[victim].inserted)) victim = i;
    }
  }
  if (victim < 0) {
    entries_.emplace_back();
    victim = static_cast<int>(entries_.size()) - 1;
  } else {
    Entry& old = entries_[victim];
    int64_t freed = 0;
    for (auto& rel : old.relations) {
      if (rel) freed += rel->bytes();
      rel.reset();
    }
    AddBytes(-freed);
    if (old.block >= 0) {  // else emptied by Finished
      entry_of_block_[old.block] = -1;
      ++stats_.evictions;
      if (trace_) trace_->Instant("evict", "buffer", {.block = old.block, .count = 1});
    }
  }
  Entry& e = entries_[victim];
  e.block = block;
  e.inserted = next_insert_++;
  entry_of_block_[block] = victim;
  return victim;
}

void CompactStructure::Reader::Finished(int32_t block) {
  const int index = entry_of_block_[block];
  if (index < 0) return;
  Entry& e = entries_[index];
  for (Slot& slot : slots_) {
    if (slot.entry != index) continue;
    --e.pins;
    slot = Slot();
  }
  if (e.pins > 0) return;
  int64_t freed = 0;
  for (auto& rel : e.relations) {
    if (rel) freed += rel->bytes();
    rel.reset();
  }
  AddBytes(-freed);
  entry_of_block_[block] = -1;
  e.block = -1;
  e.inserted = 0;  // the first to be reused
  ++stats_.evictions;
}

void CompactStructure::Reader::MoveSlot(Relation r, int32_t block) {
  Slot& slot = slots_[Index(r)];
  if (slot.entry >= 0) --entries_[slot.entry].pins;
  slot = Slot();
  ++stats_.requests;
  const int index = FindOrInsert(block);
  Entry& e = entries_[index];
  std::unique_ptr<RelationBlock>& rel = e.relations[Index(r)];
  if (rel) {
    ++stats_.hits;
  } else {
    ++stats_.misses;
    const auto start = std::chrono::steady_clock::now();
    rel = std::make_unique<RelationBlock>(ComputeBlockRelation(*topology_, r, block, scratch_));
    const auto end = std::chrono::steady_clock::now();
    stats_.wait_ns += std::chrono::duration_cast<std::chrono::nanoseconds>(end - start).count();
    if (trace_) {
      trace_->Span(RelationCode(r).data(), "consumer", start, end, {.block = block});
    }
    ++stats_.relations_computed;
    AddBytes(rel->bytes());
  }
  ++e.pins;
  slot.Point(*rel);
  slot.entry = index;
}

}  // namespace actopo
