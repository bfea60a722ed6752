// Whether a vertex lies on the boundary, from its star: each star tetrahedron's three other
// vertices give three link edges, and a link edge met exactly once is a triangle around the
// vertex that lies in one tetrahedron only (a boundary triangle). VB and critical points both
// count them this way.
//
//   LinkEdgeCounter link;          // reused across vertices
//   link.Reset(neighbors.size());  // link vertices numbered 0 .. n-1
//   for (each star tetrahedron) link.AddTriangle(a, b, c);  // the other three, as numbers
//   bool on_boundary = link.AnyOnce();
//   link.MarkOnceEnds(ends);       // which link vertices are on the boundary surely
#ifndef ACTOPO_SERVER_CORE_LINK_EDGES_H_
#define ACTOPO_SERVER_CORE_LINK_EDGES_H_

#include <algorithm>
#include <bit>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <span>
#include <vector>

#include "server/core/mesh.h"

namespace actopo {

// A vertex's link vertices (the other vertices of its star tetrahedra) numbered in the order
// first met, so the counter below and a union-find can work on small numbers. Each comes once per
// tetrahedron around its edge (a few times): a direct table over the ids near the centre vertex
// (stamped per vertex, so never cleared) and an open-addressing table, at most half full, for the
// rest keep them unique; Reset empties only the slots the last vertex used. VV, VB, critical
// points and the merge and contour trees.
class LinkVertexIndex {
 public:
  // For a star of `tetrahedra` (at most 3 link vertices each); forgets the previous vertex.
  void Reset(size_t tetrahedra) { Reset(tetrahedra, kNoCenter); }
  // The same, for the star of vertex `center`: link vertices numbered within kNear of it (most of
  // a link, as a block's vertices are numbered together) go through a direct table instead of
  // the hashed one.
  void Reset(size_t tetrahedra, SimplexId center) {
    for (uint32_t slot : used_) slot_vertex_[slot] = -1;
    used_.clear();
    vertices_.clear();
    bits_ = std::max(4, int(std::bit_width(6 * tetrahedra)));
    if (slot_vertex_.size() < (size_t(1) << bits_)) {
      slot_vertex_.assign(size_t(1) << bits_, -1);
      slot_index_.resize(size_t(1) << bits_);
    }
    near_base_ = int64_t(center) - kNear;
    if (near_stamp_.empty() || ++stamp_ == 0) {  // a new table, or the stamps went round
      near_stamp_.assign(2 * kNear, 0);
      near_index_.resize(2 * kNear);
      stamp_ = 1;
    }
  }
  // w's number, given on first sight.
  [[gnu::always_inline]] int IndexOf(SimplexId w) {
    const uint64_t near = uint64_t(int64_t(w) - near_base_);
    if (near < uint64_t(2 * kNear)) [[likely]] {
      if (near_stamp_[near] != stamp_) {
        near_stamp_[near] = stamp_;
        near_index_[near] = int(vertices_.size());
        vertices_.push_back(w);
      }
      return near_index_[near];
    }
    return HashedIndexOf(w);
  }
  // The link vertices by number.
  std::span<const SimplexId> vertices() const { return vertices_; }

 private:
  // Beyond kNear of the centre: an open-addressing table, at most half full.
  int HashedIndexOf(SimplexId w) {
    const uint64_t mask = (uint64_t(1) << bits_) - 1;
    uint64_t h = (uint64_t(uint32_t(w)) * 0x9e3779b97f4a7c15u) >> (64 - bits_);
    while (slot_vertex_[h] != w) {
      if (slot_vertex_[h] == -1) {
        slot_vertex_[h] = w;
        slot_index_[h] = int(vertices_.size());
        used_.push_back(uint32_t(h));
        vertices_.push_back(w);
        break;
      }
      h = (h + 1) & mask;
    }
    return slot_index_[h];
  }
  static constexpr int64_t kNear = 2048;
  static constexpr SimplexId kNoCenter = std::numeric_limits<SimplexId>::min();
  int bits_ = 4;
  int64_t near_base_ = int64_t(kNoCenter) - kNear;  // ids near_base_ .. + 2 kNear are direct
  uint32_t stamp_ = 0;                              // marks the current vertex's direct slots
  std::vector<uint32_t> near_stamp_;
  std::vector<int> near_index_;
  std::vector<SimplexId> slot_vertex_;
  std::vector<int> slot_index_;
  std::vector<uint32_t> used_;
  std::vector<SimplexId> vertices_;
};

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
    return ForEachKeyOnce([](size_t) { return true; });
  }

  // Sets ends[a] and ends[b] for every link edge (a, b) met once: the other two vertices of each
  // boundary triangle around the vertex, all of them on the boundary. `ends` has n entries.
  void MarkOnceEnds(std::span<uint8_t> ends) {
    if (n_ <= kMaxTable) {
      for (size_t a = 0; a < n_; ++a) {
        for (size_t b = a + 1; b < n_; ++b) {
          if (table_[a * n_ + b] == 1) ends[a] = ends[b] = 1;
        }
      }
      return;
    }
    ForEachKeyOnce([&](size_t key) {
      ends[key / n_] = ends[key % n_] = 1;
      return false;
    });
  }

 private:
  // Past kMaxTable: calls stop(key) for each key added exactly once, in ascending order, until
  // it returns true; returns whether it did.
  template <class Stop>
  bool ForEachKeyOnce(Stop&& stop) {
    std::sort(keys_.begin(), keys_.end());
    for (size_t i = 0; i < keys_.size();) {
      size_t j = i + 1;
      while (j < keys_.size() && keys_[j] == keys_[i]) ++j;
      if (j - i == 1 && stop(keys_[i])) return true;
      i = j;
    }
    return false;
  }

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
