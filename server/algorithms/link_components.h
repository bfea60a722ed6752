// The connected components of a vertex's lower and upper link, from its star alone (VT): two
// link vertices are joined when a tetrahedron of the star holds both on the same side of the
// vertex (they are then the ends of a mesh edge on that side). Critical points classify by the
// counts of components; the merge and contour trees take one vertex of each lower (upper)
// component as a candidate join (split) saddle's representative.
//
//   LinkComponents link;                        // per consumer, reused across vertices
//   link.Scan(reader, v, order);
//   for (size_t i = 0; i < link.size(); ++i)
//     if (link.IsRepresentative(i) && link.below(i)) ... link.neighbors()[i] ...
//
// The trees want one vertex per component, and links of at most 63 vertices (all but a few)
// fit a bit mask per link vertex: ScanMasked, or ScanNumbered where VV is stored (the explicit
// structure), find the components without a union-find and read each link vertex's order once
// instead of once per star tetrahedron around it (figures: bench/HISTORY.md), and hand out one
// vertex per component:
//
//   if (link.ScanMasked(reader, v, order)) link.MaskedRepresentatives(/*lower=*/true, reps);
#ifndef ACTOPO_SERVER_ALGORITHMS_LINK_COMPONENTS_H_
#define ACTOPO_SERVER_ALGORITHMS_LINK_COMPONENTS_H_

#include <algorithm>
#include <array>
#include <bit>
#include <cstdint>
#include <span>
#include <vector>

#include "server/algorithms/union_find.h"
#include "server/core/link_edges.h"
#include "server/core/relation.h"

namespace actopo {

class LinkComponents {
 public:
  // Numbers v's link vertices as its star meets them (no VV is read) and joins them, side by
  // side. `order` is VertexOrder() by internal id.
  template <class Reader>
  void Scan(Reader& reader, SimplexId v, std::span<const SimplexId> order) {
    const auto star = reader.vertex_star(v);
    index_.Reset(star.size(), v);
    triangles_.resize(star.size());
    below_.clear();
    const SimplexId ov = order[v];
    for (size_t k = 0; k < star.size(); ++k) {
      std::array<int, 3>& local = triangles_[k];
      int m = 0;
      for (SimplexId w : reader.tetrahedron_vertices(star[k])) {
        if (w == v) continue;
        const int i = index_.IndexOf(w);
        if (size_t(i) == below_.size()) below_.push_back(order[w] < ov);
        local[m++] = i;
      }
    }
    components_.Reset(below_.size());
    // A triangle's vertices on one side are joined by a chain: at most two unions, chosen by
    // the triangle's sides (bit k: vertex k is below), one branch per triangle.
    for (const std::array<int, 3>& local : triangles_) {
      const auto [a, b, c] = local;
      switch (below_[a] | below_[b] << 1 | below_[c] << 2) {
        case 0b000:
        case 0b111: components_.Union(a, b), components_.Union(b, c); break;
        case 0b011:
        case 0b100: components_.Union(a, b); break;
        case 0b101:
        case 0b010: components_.Union(a, c); break;
        default:  // 0b110, 0b001
          components_.Union(b, c);
      }
    }
  }

  // Both sides at once from v's neighbours (VV, ascending) and star: the link vertices are
  // numbered by their place in VV, so a star tetrahedron's are looked up in a table, without the
  // first-sight branch of a numbering made as the star is met, and each link vertex keeps the
  // ones it meets on its side as a bit mask. Returns false, having done nothing, when the link
  // has more than kMaxNumbered vertices: Scan then. Computing both sides costs no more than one,
  // so the join, split and contour trees share it. The table has a byte per mesh vertex (a
  // window of ids around the vertex declined too many links, whose vertices lie in other blocks).
  template <class Reader>
  bool ScanNumbered(Reader& reader, SimplexId v, std::span<const SimplexId> order) {
    const auto vv = reader.vertex_neighbors(v);
    const size_t n = vv.size();
    if (n == 0 || n > kMaxNumbered) return false;
    if (local_.empty()) local_.resize(size_t(reader.topology().num_vertices()));
    const SimplexId ov = order[v];
    uint64_t below = 0;
    for (size_t i = 0; i < n; ++i) {
      local_[vv[i]] = uint8_t(i);
      below |= uint64_t(order[vv[i]] < ov) << i;
      same_side_[i] = 0;
    }
    local_[v] = kCenter;  // bit kCenter is on neither side
    const uint64_t above = ((uint64_t(1) << n) - 1) & ~below;
    for (SimplexId t : reader.vertex_star(v)) {
      const auto tuple = reader.tetrahedron_vertices(t);
      JoinSides({local_[tuple[0]], local_[tuple[1]], local_[tuple[2]], local_[tuple[3]]}, below,
                above);
    }
    numbered_below_ = below;
    numbered_above_ = above;
    numbered_neighbors_ = vv;
    return true;
  }

  // The same masks without VV: the link vertices are numbered as the star meets them (the
  // centre first, as number 0), each one's side is read once, then the star's tetrahedra, kept
  // as numbers, are joined as in ScanNumbered. Returns false when the link has more than
  // kMaxNumbered vertices: Scan then.
  template <class Reader>
  bool ScanMasked(Reader& reader, SimplexId v, std::span<const SimplexId> order) {
    const auto star = reader.vertex_star(v);
    index_.Reset(star.size(), v);
    index_.IndexOf(v);
    local_tetrahedra_.resize(star.size());
    for (size_t k = 0; k < star.size(); ++k) {
      const auto tuple = reader.tetrahedron_vertices(star[k]);
      for (int j = 0; j < 4; ++j) local_tetrahedra_[k][j] = uint8_t(index_.IndexOf(tuple[j]));
    }
    const std::span<const SimplexId> link = index_.vertices();  // link[0] is v
    if (link.size() > kMaxNumbered + 1) return false;
    const SimplexId ov = order[v];
    uint64_t below = 0;
    for (size_t i = 1; i < link.size(); ++i) {
      below |= uint64_t(order[link[i]] < ov) << i;
      same_side_[i] = 0;
    }
    const uint64_t above = (((uint64_t(2) << (link.size() - 1)) - 1) & ~uint64_t(1)) & ~below;
    for (const std::array<uint8_t, 4>& local : local_tetrahedra_) JoinSides(local, below, above);
    numbered_below_ = below;
    numbered_above_ = above;
    numbered_neighbors_ = link;
    return true;
  }

  // After ScanNumbered (before the reader is asked for VV again) or ScanMasked: one vertex of
  // each component of the lower (`lower`) or upper link, the first numbered of each, into `reps`
  // (cleared first).
  void MaskedRepresentatives(bool lower, std::vector<SimplexId>& reps) const {
    reps.clear();
    for (uint64_t left = lower ? numbered_below_ : numbered_above_; left != 0;) {
      const uint64_t seed = left & -left;
      uint64_t component = seed, frontier = seed;
      while (frontier != 0) {
        const int i = std::countr_zero(frontier);
        frontier &= frontier - 1;
        const uint64_t reached = same_side_[size_t(i)] & ~component;
        component |= reached;
        frontier |= reached;
      }
      left &= ~component;
      reps.push_back(numbered_neighbors_[size_t(std::countr_zero(seed))]);
    }
  }

  // The link vertices (internal ids), numbered as the star met them.
  std::span<const SimplexId> neighbors() const { return index_.vertices(); }
  size_t size() const { return index_.vertices().size(); }
  // Whether link vertex i is lower than v in the order.
  bool below(size_t i) const { return below_[i] != 0; }
  // Whether link vertex i stands for its component (one per component).
  bool IsRepresentative(size_t i) { return components_.Find(int32_t(i)) == int32_t(i); }
  // Per star tetrahedron, its link triangle in link vertex numbers.
  std::span<const std::array<int, 3>> triangles() const { return triangles_; }

 private:
  // One star tetrahedron, its vertices as numbers: each meets the others on its side (the
  // centre's entry is a spare nobody reads).
  [[gnu::always_inline]] void JoinSides(std::array<uint8_t, 4> local, uint64_t below,
                                        uint64_t above) {
    const uint64_t b0 = uint64_t(1) << local[0], b1 = uint64_t(1) << local[1],
                   b2 = uint64_t(1) << local[2], b3 = uint64_t(1) << local[3];
    const uint64_t in = b0 | b1 | b2 | b3;
    const uint64_t lower = in & below, upper = in & above;
    same_side_[local[0]] |= (b0 & below) ? lower : upper;
    same_side_[local[1]] |= (b1 & below) ? lower : upper;
    same_side_[local[2]] |= (b2 & below) ? lower : upper;
    same_side_[local[3]] |= (b3 & below) ? lower : upper;
  }

  static constexpr size_t kMaxNumbered = 63;  // bit 63 is the centre's
  static constexpr uint8_t kCenter = 63;
  std::vector<uint8_t> local_;  // ScanNumbered: by vertex id, its place in the last VV read
  std::vector<std::array<uint8_t, 4>> local_tetrahedra_;  // ScanMasked: the star as numbers
  // ScanNumbered: per link vertex (and the centre's spare), the link vertices on its side that
  // share a star tetrahedron with it; and each side's link vertices.
  std::array<uint64_t, kMaxNumbered + 1> same_side_{};
  uint64_t numbered_below_ = 0, numbered_above_ = 0;
  std::span<const SimplexId> numbered_neighbors_;  // VV of the vertex
  UnionFind components_;                           // over the link vertices (a few tens)
  LinkVertexIndex index_;
  std::vector<std::array<int, 3>> triangles_;
  std::vector<uint8_t> below_;
};

}  // namespace actopo

#endif  // ACTOPO_SERVER_ALGORITHMS_LINK_COMPONENTS_H_
