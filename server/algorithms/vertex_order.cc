#include "server/algorithms/vertex_order.h"

#include <algorithm>

#include "server/core/parallel.h"

namespace actopo {
namespace {

// Sorted by value, then input id. Sorting these keys themselves, not ids compared through the
// scalar array, keeps the comparisons in cache instead of a miss per look-up. Packed to 12
// bytes: with the ranks (4), the order's peak is 16 bytes per vertex, not 28 (16-byte keys,
// then a merge buffer of half of them), and it can be the peak of a critical points run.
#pragma pack(push, 4)
struct Key {
  double value;
  SimplexId id;
  bool operator<(const Key& o) const { return value < o.value || (value == o.value && id < o.id); }
};
#pragma pack(pop)
static_assert(sizeof(Key) == 12);

}  // namespace

std::vector<SimplexId> VertexOrder(const Topology& topology, std::span<const double> scalars,
                                   int threads) {
  const SimplexId n = topology.num_vertices();
  std::vector<Key> keys(n);
  for (SimplexId v = 0; v < n; ++v) keys[v] = {scalars[v], v};
  // Runs sorted on every core, merged pairwise in place until two are left, which are merged
  // straight into the ranks.
  const int64_t runs = std::clamp<int64_t>(threads > 0 ? threads : DefaultThreads(), 1,
                                           std::max<int64_t>(n / 65536, 1));
  std::vector<int64_t> bound(runs + 1);
  for (int64_t r = 0; r <= runs; ++r) bound[r] = n * r / runs;
  ParallelFor(runs, int(runs), [&](int64_t r, int) {
    std::sort(keys.begin() + bound[r], keys.begin() + bound[r + 1]);
  });
  int64_t width = 1;
  for (; 2 * width < runs; width *= 2) {
    for (int64_t r = 0; r + width < runs; r += 2 * width) {
      const int64_t end = bound[std::min(r + 2 * width, runs)];
      std::inplace_merge(keys.begin() + bound[r], keys.begin() + bound[r + width],
                         keys.begin() + end);
    }
  }
  // The last merge: the lower half of the ranks from the fronts of both runs, the upper half
  // from their backs, on two threads. Keys are distinct (ids), so both halves agree on the cut.
  std::vector<SimplexId> order(n);
  const Key* const a_begin = keys.data();
  const Key* const b_begin = keys.data() + (runs > 1 ? bound[width] : n);
  const Key* const b_end = keys.data() + n;
  const SimplexId half = n / 2;
  ParallelFor(2, runs > 1 ? 2 : 1, [&](int64_t side, int) {
    if (side == 0) {
      const Key *a = a_begin, *b = b_begin;
      for (SimplexId rank = 0; rank < half; ++rank) {
        const Key& k = (b == b_end || (a != b_begin && *a < *b)) ? *a++ : *b++;
        order[topology.vertex_internal_id(k.id)] = rank;
      }
    } else {
      const Key *a = b_begin, *b = b_end;  // one past the last unmerged key of each run
      for (SimplexId rank = n - 1; rank >= half; --rank) {
        const Key& k = (a == a_begin || (b != b_begin && *(a - 1) < *(b - 1))) ? *--b : *--a;
        order[topology.vertex_internal_id(k.id)] = rank;
      }
    }
  });
  return order;
}

}  // namespace actopo
