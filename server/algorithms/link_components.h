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
#ifndef ACTOPO_SERVER_ALGORITHMS_LINK_COMPONENTS_H_
#define ACTOPO_SERVER_ALGORITHMS_LINK_COMPONENTS_H_

#include <array>
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
    index_.Reset(star.size());
    triangles_.clear();
    for (SimplexId t : star) {
      std::array<int, 3>& local = triangles_.emplace_back();
      int m = 0;
      for (SimplexId w : reader.tetrahedron_vertices(t)) {
        if (w != v) local[m++] = index_.IndexOf(w);
      }
    }
    const std::span<const SimplexId> link = index_.vertices();
    const SimplexId ov = order[v];
    below_.resize(link.size());
    for (size_t i = 0; i < link.size(); ++i) below_[i] = order[link[i]] < ov;
    components_.Reset(link.size());
    // A triangle's vertices on one side are joined by a chain: at most two unions.
    for (const std::array<int, 3>& local : triangles_) {
      int last[2] = {-1, -1};  // per side (0 upper, 1 lower): the previous vertex
      for (int i : local) {
        const int side = below_[i];
        if (last[side] >= 0) components_.Union(last[side], i);
        last[side] = i;
      }
    }
  }

  // Only the link vertices on one side of v (lower, or upper), numbered and joined: a merge
  // tree needs one side, and the other's are never looked up.
  template <class Reader>
  void ScanSide(Reader& reader, SimplexId v, std::span<const SimplexId> order, bool lower) {
    const auto star = reader.vertex_star(v);
    index_.Reset(star.size());
    components_.Reset(0);
    const SimplexId ov = order[v];
    for (SimplexId t : star) {
      int last = -1;  // the tetrahedron's side is joined by a chain
      for (SimplexId w : reader.tetrahedron_vertices(t)) {
        if (w == v || (order[w] < ov) != lower) continue;
        const int i = index_.IndexOf(w);
        if (size_t(i) == components_.size()) components_.Add();
        if (last >= 0) components_.Union(last, i);
        last = i;
      }
    }
    below_.assign(index_.vertices().size(), lower ? 1 : 0);
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
  UnionFind components_;  // over the link vertices (a few tens)
  LinkVertexIndex index_;
  std::vector<std::array<int, 3>> triangles_;
  std::vector<uint8_t> below_;
};

}  // namespace actopo

#endif  // ACTOPO_SERVER_ALGORITHMS_LINK_COMPONENTS_H_
