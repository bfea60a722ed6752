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
inline int DefaultThreads() {
  return std::max(1u, std::thread::hardware_concurrency());
}

// The threads of a run when the user names none: every core busy, none oversubscribed.
// explicit and compact run one consumer per core. actopo gives half the cores to consumers and
// the rest to their producers (one leader each, workers when cores allow), at least one of each:
// 1 or 2 cores -> 1 consumer with 1 producer, 3 -> 1 with 2, 4 -> 2 with 1, 8 -> 4 with 1.
// Measured on 2 cores (bench/RESULTS.md): actopo with 1 consumer and 1 producer beat 1 with 2
// and 2 with 1; explicit and compact gain from a second consumer.
struct ThreadPlan {
  int consumers = 1;
  int producers = 0;  // per consumer; 0 for explicit and compact
};
inline ThreadPlan DefaultThreadPlan(bool task_parallel, int cores = DefaultThreads()) {
  cores = std::max(cores, 1);
  if (!task_parallel) return {cores, 0};
  const int consumers = std::max(1, cores / 2);
  return {consumers, std::max(1, cores / consumers - 1)};
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

}  // namespace actopo

#endif  // ACTOPO_SERVER_CORE_PARALLEL_H_
