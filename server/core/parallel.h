// A minimal block-parallel loop for preprocessing (partition, encodings, explicit relations).
//
//   ParallelFor(num_blocks, threads, [&](int64_t block, int thread) { ... });
//
// Items are handed out one at a time through an atomic counter, so uneven blocks balance out.
// With threads <= 1 the loop runs inline, which keeps small meshes and tests deterministic.
#ifndef ACTOPO_SERVER_CORE_PARALLEL_H_
#define ACTOPO_SERVER_CORE_PARALLEL_H_

#include <algorithm>
#include <atomic>
#include <cstdint>
#include <thread>
#include <vector>

namespace actopo {

// Default worker count for preprocessing: the hardware concurrency, at least 1.
inline int DefaultThreads() { return std::max(1u, std::thread::hardware_concurrency()); }

// The threads of a run when the user names none: one consumer per core for every structure, and
// for actopo one producer (a leader) per consumer. actopo's threads outnumber the cores, which is
// the point: a producer computes while its consumer waits and sleeps while its buffer is full;
// with a consumer on every core the producers run at idle priority (DefaultProducerPriority in
// server/algorithms/structure_options.h), so they take no cycles a consumer wants.
// On 2 cores (bench/RESULTS.md, "Threads and the engine's defaults"), 2 consumers with 1
// producer each take less time than 1 with 1 on the algorithms that read many relations, at the
// same peak memory; critical points, whose run is a small part of its process, gains nothing.
struct ThreadPlan {
  int consumers = 1;
  int producers = 0;  // per consumer; 0 for explicit and compact
};
inline ThreadPlan DefaultThreadPlan(bool task_parallel, int cores = DefaultThreads()) {
  cores = std::max(cores, 1);
  return {cores, task_parallel ? 1 : 0};
}

template <class Fn>
void ParallelFor(int64_t n, int threads, Fn&& fn) {
  threads = static_cast<int>(std::min<int64_t>(std::max(threads, 1), std::max<int64_t>(n, 1)));
  if (threads <= 1) {
    for (int64_t i = 0; i < n; ++i) fn(i, 0);
    return;
  }
  std::atomic<int64_t> next{0};
  auto work = [&](int thread) {
    for (int64_t i = next.fetch_add(1, std::memory_order_relaxed); i < n;
         i = next.fetch_add(1, std::memory_order_relaxed)) {
      fn(i, thread);
    }
  };
  std::vector<std::thread> pool;
  pool.reserve(threads - 1);
  for (int t = 1; t < threads; ++t) pool.emplace_back(work, t);
  work(0);
  for (std::thread& t : pool) t.join();
}

// fn(begin, end) over [0, n) in ranges of `chunk` items on `threads` threads: for passes that
// cost little per item (a fill, a permutation, a label lookup), where one task per item would
// cost more than the item.
template <class Fn>
void ParallelForRanges(int64_t n, int64_t chunk, int threads, Fn&& fn) {
  chunk = std::max<int64_t>(chunk, 1);
  ParallelFor((n + chunk - 1) / chunk, threads,
              [&](int64_t c, int) { fn(c * chunk, std::min(n, (c + 1) * chunk)); });
}

}  // namespace actopo

#endif  // ACTOPO_SERVER_CORE_PARALLEL_H_
