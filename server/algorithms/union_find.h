// Disjoint sets over 0..n-1 (union-find), shared by the algorithms that grow components: a
// vertex link's components (critical points), the extrema's components (persistence pairs),
// the flattened maxima (simplification), the trees' arcs.
//
//   UnionFind sets(n);
//   sets.Union(a, b);                            // b's root becomes the union's root
//   if (sets.Find(a) == sets.Find(c)) ...
//   sets.Link(dying_root, surviving_root);       // the caller chose which root survives
//
// Find halves paths as it walks; which root represents a set depends only on the links made,
// never on that compression, so results do not depend on the order of finds.
#ifndef ACTOPO_SERVER_ALGORITHMS_UNION_FIND_H_
#define ACTOPO_SERVER_ALGORITHMS_UNION_FIND_H_

#include <cstddef>
#include <cstdint>
#include <vector>

namespace actopo {

class UnionFind {
 public:
  UnionFind() = default;
  explicit UnionFind(size_t n) { Reset(n); }

  // n singletons; the storage is kept for reuse (a scratch per consumer).
  void Reset(size_t n) {
    parent_.resize(n);
    for (size_t i = 0; i < n; ++i) parent_[i] = int32_t(i);
  }
  size_t size() const { return parent_.size(); }
  // One more singleton; returns it.
  int32_t Add() {
    parent_.push_back(int32_t(parent_.size()));
    return parent_.back();
  }

  int32_t Find(int32_t x) {
    while (parent_[x] != x) x = parent_[x] = parent_[parent_[x]];
    return x;
  }
  bool IsRoot(int32_t x) const { return parent_[x] == x; }
  // A hint: x's entry will be read soon.
  void Prefetch(int32_t x) const { __builtin_prefetch(&parent_[x]); }

  // Makes root `child` a child of root `root` (both must be roots).
  void Link(int32_t child, int32_t root) { parent_[child] = root; }

  // Joins the sets of a and b; returns the union's root, b's.
  int32_t Union(int32_t a, int32_t b) {
    const int32_t root = Find(b);
    parent_[Find(a)] = root;
    return root;
  }

 private:
  std::vector<int32_t> parent_;
};

}  // namespace actopo

#endif  // ACTOPO_SERVER_ALGORITHMS_UNION_FIND_H_
