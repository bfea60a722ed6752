// Counters a structure reports about its relation accesses and memory.
//
// A "request" is a lookup of (block, relation) made when a reader moves to another block for a
// relation; reads inside the block it is already on are not counted (they cost one comparison).
// A hit finds the block's relation ready; a miss has to wait for it to be computed. For the
// compact structure the consumer computes it itself, so its wait is its own compute time.
#ifndef ACTOPO_SERVER_CORE_STATS_H_
#define ACTOPO_SERVER_CORE_STATS_H_

#include <algorithm>
#include <cstdint>

namespace actopo {

struct AccessStats {
  int64_t requests = 0;
  int64_t hits = 0;
  int64_t misses = 0;
  int64_t evictions = 0;           // blocks dropped from a cache or buffer
  int64_t relations_computed = 0;  // (block, relation) computations
  int64_t wait_ns = 0;             // time consumers waited for missing relations

  AccessStats& operator+=(const AccessStats& o) {
    requests += o.requests;
    hits += o.hits;
    misses += o.misses;
    evictions += o.evictions;
    relations_computed += o.relations_computed;
    wait_ns += o.wait_ns;
    return *this;
  }
  // Counts since `before` (a snapshot of the same counters).
  AccessStats Since(const AccessStats& before) const {
    return {.requests = requests - before.requests,
            .hits = hits - before.hits,
            .misses = misses - before.misses,
            .evictions = evictions - before.evictions,
            .relations_computed = relations_computed - before.relations_computed,
            .wait_ns = wait_ns - before.wait_ns};
  }
};

struct MemoryStats {
  int64_t static_bytes = 0;         // the shared Topology
  int64_t relation_bytes = 0;       // explicit: all stored relations; else cache/buffer now
  int64_t relation_peak_bytes = 0;  // explicit: same as relation_bytes; else the peak
};

}  // namespace actopo

#endif  // ACTOPO_SERVER_CORE_STATS_H_
