// Whether a vertex lies on the boundary, from its star: each star tetrahedron's three other
// vertices give three link edges, and a link edge met exactly once is a triangle around the
// vertex that lies in one tetrahedron only (a boundary triangle). VB and critical points both
// count them this way.
//
//   LinkEdgeCounter link;          // reused across vertices
//   link.Reset(neighbors.size());  // link vertices numbered 0 .. n-1
//   for (each star tetrahedron) link.AddTriangle(a, b, c);  // the other three, as numbers
//   bool on_boundary = link.AnyOnce();
#ifndef ACTOPO_SERVER_CORE_LINK_EDGES_H_
#define ACTOPO_SERVER_CORE_LINK_EDGES_H_

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <vector>

namespace actopo {

class LinkEdgeCounter {
 public:
  // Counts in an n x n table (saturating at 2) for the usual tens of link vertices; beyond
  // kMaxTable, as keys sorted at the end.
  static constexpr size_t kMaxTable = 64;

  void Reset(size_t n) {
    n_ = n;
    if (n <= kMaxTable) {
      table_.assign(n * n, 0);
    } else {
      keys_.clear();
    }
  }

  // The link edges of one star tetrahedron whose other vertices are numbered a, b, c.
  void AddTriangle(size_t a, size_t b, size_t c) {
    if (a > b) std::swap(a, b);
    if (b > c) std::swap(b, c);
    if (a > b) std::swap(a, b);
    Add(a * n_ + b);
    Add(a * n_ + c);
    Add(b * n_ + c);
  }

  bool AnyOnce() {
    if (n_ <= kMaxTable) return std::find(table_.begin(), table_.end(), 1) != table_.end();
    std::sort(keys_.begin(), keys_.end());
    for (size_t i = 0; i < keys_.size();) {
      size_t j = i + 1;
      while (j < keys_.size() && keys_[j] == keys_[i]) ++j;
      if (j - i == 1) return true;
      i = j;
    }
    return false;
  }

 private:
  void Add(size_t key) {
    if (n_ <= kMaxTable) {
      uint8_t& seen = table_[key];
      seen = seen < 2 ? seen + 1 : 2;
    } else {
      keys_.push_back(key);
    }
  }

  size_t n_ = 0;
  std::vector<uint8_t> table_;
  std::vector<size_t> keys_;
};

}  // namespace actopo

#endif  // ACTOPO_SERVER_CORE_LINK_EDGES_H_
