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
// fit a bit mask: ScanMasked, or ScanNumbered where VV is stored (the explicit structure), find
// the components without a union-find, read each link vertex's order once instead of once per
// star tetrahedron around it. Critical points count them after ScanMasked, which also gives the
// ends of v's boundary triangles (MaskedBoundaryEnds). A merge tree, one side, needs less than
// the link: ScanByEdges groups the side's neighbours by the mesh edges between them, from VV
// alone (figures: bench/HISTORY.md). Then one vertex per component or group:
//
//   if (link.ScanMasked(reader, v, order, LinkComponents::kLower))
//     link.MaskedRepresentatives(/*lower=*/true, reps);
#ifndef ACTOPO_SERVER_ALGORITHMS_LINK_COMPONENTS_H_
#define ACTOPO_SERVER_ALGORITHMS_LINK_COMPONENTS_H_

#include <algorithm>
#include <array>
#include <bit>
#include <cstdint>
#include <span>
#include <utility>
#include <vector>

#include "server/algorithms/union_find.h"
#include "server/core/link_edges.h"
#include "server/core/relation.h"
#include "server/core/topology.h"

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

  // Which sides of the link the mask scans find the components of.
  enum Sides : uint8_t { kLower = 1, kUpper = 2, kBothSides = 3 };

  // From v's neighbours (VV, ascending) and star: the link vertices are numbered by their place
  // in VV, so a star tetrahedron's are looked up in a table, without the first-sight branch of a
  // numbering made as the star is met; each star tetrahedron's vertices on a side become a mask
  // (the star is not read when each side asked for has at most one vertex). Returns false,
  // having done nothing, when the link has more than kMaxNumbered vertices: Scan then. Both
  // sides cost little more than one, so the contour tree asks for both. The table has a byte per
  // mesh vertex (a window of ids around the vertex declined too many links, whose vertices lie
  // in other blocks).
  template <class Reader>
  bool ScanNumbered(Reader& reader, SimplexId v, std::span<const SimplexId> order,
                    Sides sides = kBothSides) {
    const auto vv = reader.vertex_neighbors(v);
    const size_t n = vv.size();
    if (n == 0 || n > kMaxNumbered) return false;
    const auto [below, above] = NumberNeighbors(numbered_, reader.topology(), vv, order[v], order);
    // v's own entry may still hold its place in an earlier vertex's VV. The others are left as
    // they are after the scan, which saves a store per neighbour on the contour tree's hot path:
    // a star holds v's neighbours only, and they were all numbered afresh above.
    numbered_[v] = kCenter;
    if (!StartSides(sides, below, above)) {
      const auto star = reader.vertex_star(v);
      lower_.Reserve(star.size());
      upper_.Reserve(star.size());
      for (SimplexId t : star) {
        const auto tuple = reader.tetrahedron_vertices(t);
        AddTetrahedron(
            {numbered_[tuple[0]], numbered_[tuple[1]], numbered_[tuple[2]], numbered_[tuple[3]]});
      }
    }
    return true;
  }

  // Coarser than the link and cheaper for one side: the side's neighbours (VV) in groups joined
  // by the mesh edges between them, read from the neighbours' own VV, without the star. A group
  // is connected on its side of v, which is all a merge tree asks, but may hold several link
  // components (two lower neighbours joined by an edge outside v's star): not for critical
  // points. Reads the VV of up to every neighbour on the wanted sides, so ScanNumbered is
  // cheaper for both. The reader's VV rows must stay where they are while others are read (a
  // structure with its relations in place). Returns false when v has more than kMaxNumbered
  // neighbours. MaskedRepresentatives then names a vertex per group.
  template <class Reader>
  bool ScanByEdges(Reader& reader, SimplexId v, std::span<const SimplexId> order, Sides sides) {
    const auto vv = reader.vertex_neighbors(v);
    const size_t n = vv.size();
    if (n == 0 || n > kMaxNumbered) return false;
    const auto [below, above] = NumberNeighbors(grouped_, reader.topology(), vv, order[v], order);
    if (!StartSides(sides, below, above)) {
      for (SideMasks* side : {&lower_, &upper_}) {
        if ((side->vertices & (side->vertices - 1)) != 0) GroupByEdges(reader, vv, *side);
      }
    }
    for (SimplexId w : vv) grouped_[w] = kCenter;  // the neighbours' VV hold other vertices
    return true;
  }

  // The same masks without VV: the link vertices are numbered as the star meets them (the
  // centre first, as number 0), each one's side is read once, then the star's tetrahedra, kept
  // as numbers, are met as in ScanNumbered. Returns false when the link has more than
  // kMaxNumbered vertices: Scan then.
  template <class Reader>
  bool ScanMasked(Reader& reader, SimplexId v, std::span<const SimplexId> order,
                  Sides sides = kBothSides) {
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
    for (size_t i = 1; i < link.size(); ++i) below |= uint64_t(order[link[i]] < ov) << i;
    const uint64_t above = (((uint64_t(2) << (link.size() - 1)) - 1) & ~uint64_t(1)) & ~below;
    numbered_neighbors_ = link;
    if (StartSides(sides, below, above)) return true;
    lower_.Reserve(star.size());
    upper_.Reserve(star.size());
    for (const std::array<uint8_t, 4>& local : local_tetrahedra_) AddTetrahedron(local);
    return true;
  }

  // After ScanNumbered, ScanByEdges (before the reader is asked for v's VV again) or ScanMasked,
  // for a side they were asked for: one vertex of each component (group) of the lower (`lower`)
  // or upper link into `reps` (cleared first).
  void MaskedRepresentatives(bool lower, std::vector<SimplexId>& reps) const {
    reps.clear();
    const SideMasks& side = lower ? lower_ : upper_;
    for (uint64_t left = side.vertices; left != 0;) {
      // From its first vertex, grown through every kept mask that meets it until a pass adds
      // nothing (a connected side, most of them: two or three passes).
      uint64_t component = left & -left;
      for (uint64_t before = 0; component != before && component != left;) {
        before = component;
        for (size_t k = 0; k < side.num_masks; ++k) {
          const uint64_t m = side.masks[k];
          component |= (m & component) ? m : 0;
        }
      }
      reps.push_back(numbered_neighbors_[size_t(std::countr_zero(component))]);
      left &= ~component;
    }
  }

  // After ScanMasked, by its numbers (bit i: link vertex i, bit 0 the centre): the vertices of
  // the side asked for (`lower` or upper), and the ends of the link edges that one star
  // tetrahedron alone holds, which are the ends of the boundary triangles around v (none inside
  // the mesh). Per link vertex, the link edges met once and those met again are two masks.
  uint64_t MaskedSide(bool lower) const { return (lower ? lower_ : upper_).vertices; }
  uint64_t MaskedBoundaryEnds() {
    const size_t n = index_.vertices().size();
    once_.assign(n, 0);
    twice_.assign(n, 0);
    for (const std::array<uint8_t, 4>& local : local_tetrahedra_) {
      const uint64_t triangle = (uint64_t(1) << local[0] | uint64_t(1) << local[1] |
                                 uint64_t(1) << local[2] | uint64_t(1) << local[3]) &
                                ~uint64_t(1);
      for (uint64_t left = triangle; left != 0; left &= left - 1) {
        const int i = std::countr_zero(left);
        const uint64_t others = triangle & ~(uint64_t(1) << i);
        twice_[size_t(i)] |= once_[size_t(i)] & others;
        once_[size_t(i)] |= others;
      }
    }
    uint64_t ends = 0;
    for (size_t i = 1; i < n; ++i) ends |= once_[i] & ~twice_[i];
    return ends;
  }
  // Link vertex i of ScanMasked's numbering (0 is the centre).
  SimplexId MaskedVertex(int i) const { return numbered_neighbors_[size_t(i)]; }

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
  // One side of the link: its vertices, and each star tetrahedron's vertices on it when they are
  // two or more (a lone one joins nothing), for MaskedRepresentatives' closure. ScanByEdges keeps
  // its groups there instead, each whole.
  struct SideMasks {
    uint64_t vertices = 0;
    std::vector<uint64_t> masks;
    size_t num_masks = 0;

    // Whether the side needs no masks: at most one vertex (or none: not wanted).
    bool Start(uint64_t side) {
      vertices = side;
      num_masks = 0;
      return (side & (side - 1)) == 0;
    }
    void Reserve(size_t count) {
      if (masks.size() < count + 1) masks.resize(count + 1);
    }
    // Without a branch on the data: the count moves on only when the mask is kept.
    [[gnu::always_inline]] void Add(uint64_t in) {
      const uint64_t m = in & vertices;
      masks[num_masks] = m;
      num_masks += (m & (m - 1)) != 0;
    }
  };

  // Numbers v's neighbours by their place in VV in `table` (a byte per mesh vertex, kCenter
  // until written); returns the masks of those below and above v.
  std::pair<uint64_t, uint64_t> NumberNeighbors(std::vector<uint8_t>& table,
                                                const Topology& topology,
                                                std::span<const SimplexId> vv, SimplexId ov,
                                                std::span<const SimplexId> order) {
    if (table.empty()) table.assign(size_t(topology.num_vertices()), kCenter);
    numbered_neighbors_ = vv;
    uint64_t below = 0;
    for (size_t i = 0; i < vv.size(); ++i) {
      table[vv[i]] = uint8_t(i);
      below |= uint64_t(order[vv[i]] < ov) << i;
    }
    return {below, ((uint64_t(1) << vv.size()) - 1) & ~below};
  }
  // The side's groups, breadth-first over the edges between its vertices, each kept as one mask.
  // A walk stops once its group holds all the side's vertices not yet grouped.
  template <class Reader>
  void GroupByEdges(Reader& reader, std::span<const SimplexId> vv, SideMasks& side) {
    side.Reserve(vv.size());
    for (uint64_t left = side.vertices; left != 0;) {
      uint64_t group = left & -left, frontier = group;
      while (frontier != 0 && group != left) {
        const int i = std::countr_zero(frontier);
        frontier &= frontier - 1;
        uint64_t adjacent = 0;
        for (SimplexId w : reader.vertex_neighbors(vv[size_t(i)])) {
          adjacent |= uint64_t(1) << grouped_[w];
        }
        adjacent &= left & ~group;
        group |= adjacent;
        frontier |= adjacent;
      }
      side.masks[side.num_masks++] = group;
      left &= ~group;
    }
  }

  // Both sides' masks for a new vertex; true when no tetrahedron needs reading.
  bool StartSides(Sides sides, uint64_t below, uint64_t above) {
    const bool lower_known = lower_.Start(sides & kLower ? below : 0);
    return upper_.Start(sides & kUpper ? above : 0) && lower_known;
  }
  // One star tetrahedron, its vertices as numbers (the centre's bit is on neither side).
  [[gnu::always_inline]] void AddTetrahedron(std::array<uint8_t, 4> local) {
    const uint64_t in = uint64_t(1) << local[0] | uint64_t(1) << local[1] |
                        uint64_t(1) << local[2] | uint64_t(1) << local[3];
    lower_.Add(in);
    upper_.Add(in);
  }

  static constexpr size_t kMaxNumbered = 63;  // bit 63 is the centre's
  static constexpr uint8_t kCenter = 63;
  // By vertex id, its place in the VV of the vertex scanned: ScanNumbered's holds stale places
  // of other vertices; ScanByEdges' holds kCenter (on neither side) for every vertex between
  // scans, as it reads the neighbours' VV, which hold vertices that are not v's neighbours.
  std::vector<uint8_t> numbered_, grouped_;
  std::vector<std::array<uint8_t, 4>> local_tetrahedra_;  // ScanMasked: the star as numbers
  std::vector<uint64_t> once_, twice_;  // MaskedBoundaryEnds: per link vertex, its link edges
  SideMasks lower_, upper_;
  std::span<const SimplexId> numbered_neighbors_;  // VV of the vertex
  UnionFind components_;                           // over the link vertices (a few tens)
  LinkVertexIndex index_;
  std::vector<std::array<int, 3>> triangles_;
  std::vector<uint8_t> below_;
};

}  // namespace actopo

#endif  // ACTOPO_SERVER_ALGORITHMS_LINK_COMPONENTS_H_
