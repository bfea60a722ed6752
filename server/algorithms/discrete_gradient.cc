#include "server/algorithms/discrete_gradient.h"

#include <algorithm>
#include <bit>
#include <optional>
#include <type_traits>
#include <utility>

#include "absl/strings/str_cat.h"
#include "server/algorithms/digest.h"
#include "server/algorithms/prefetch_off.h"
#include "server/core/actopo_structure.h"
#include "server/core/compact_structure.h"
#include "server/core/explicit_structure.h"
#include "server/core/parallel.h"
#include "server/core/status_macros.h"
#include "server/core/structures.h"

namespace actopo {
namespace {

// A cell of a vertex x's lower star. Cells compare by key: the orders of their vertices other
// than x, descending, padded with a value below every order (so across dimensions too). A star
// holds its edges, triangles and tetrahedra by key, so a cell's place is its rank.
struct StarCell {
  SimplexId id;
  std::array<int32_t, 3> faces;  // the ranks of its faces that contain x, `dim` of them
  uint8_t dim;                   // 1, 2 or 3; an edge's face is x, which the star does not hold
  bool paired;
};

// A set of a lower star's cell ranks, taken out smallest first: one bit per rank. It stands for
// the two priority queues of the pairing (Robins et al.'s PQzero and PQone), whose elements are
// few (tens) and compared by key; ranks compare as their keys do. A rank already in the set is
// not added twice, which changes nothing: a cell taken out a second time would have no unpaired
// face left (it was paired, or went to PQzero, the first time), and one in PQzero twice would be
// skipped as paired the second time.
class RankSet {
 public:
  void Reset(size_t ranks) {
    words_.assign((ranks + 63) / 64, 0);
    first_ = words_.size();
  }
  bool empty() const { return first_ == words_.size(); }
  void Insert(int32_t rank) {
    const size_t w = size_t(rank) >> 6;
    words_[w] |= uint64_t(1) << (rank & 63);
    first_ = std::min(first_, w);
  }
  int32_t Min() const { return int32_t(first_ * 64 + std::countr_zero(words_[first_])); }
  int32_t PopMin() {
    const int32_t rank = Min();
    words_[first_] &= words_[first_] - 1;
    while (first_ < words_.size() && words_[first_] == 0) ++first_;
    return rank;
  }

 private:
  std::vector<uint64_t> words_;
  size_t first_ = 0;  // the first nonzero word; words_.size() when empty
};

// Pairs lower stars (Robins et al.'s ProcessLowerStars) into a GradientField. A star is built in
// three lists, each sorted by a key of small integers before the next is read: its edges by the
// order of their other vertex, which numbers them (an edge's index stands for that order in the
// keys after it, comparing as the order does); its triangles by their two edges' indices, higher
// first, which are also their faces; its tetrahedra by their highest triangle's index and their
// lowest edge's, their three triangles found by search among the sorted ones. One merge of the
// three lists then ranks every cell, so the pairing works on small ranks with no indirection
// instead of sorting wide keys of orders together and scanning the star for faces.
class LowerStarPairing {
 public:
  LowerStarPairing(GradientField& gradient, const Topology& topology)
      : gradient_(gradient), topology_(topology) {}

  // The critical cells and the pairs (per lower dimension) of the lower stars processed so far.
  std::array<std::vector<SimplexId>, 4>& critical() { return critical_; }
  const std::array<int64_t, 3>& pairs() const { return pairs_; }

  // Pairs the cells of x's lower star, read from the structure's VE, VF and VT.
  template <class Reader>
  void Process(Reader& reader, SimplexId x, std::span<const SimplexId> order) {
    Build(reader, x, order);
    PairStar(x);
  }

  // Has Process record `links` (AscendingLinks), as consumer `consumer`.
  void RecordLinks(AscendingLinks* links, int consumer) {
    links_ = links;
    consumer_ = consumer;
  }

  // The same for a gradient being updated to a new order: first forgets what the gradient held
  // for the star's cells (critical cells are left unwritten). With `from_tetrahedra`, the star is
  // read from VT alone and the static encoding's lookups (FindEdge, FindTriangle), for structures
  // that compute relations by block: an update pairs a few stars of each block it visits, and a
  // block's VE and VF cost more than its VT. Explicit, which holds VE and VF, stays faster
  // reading them.
  template <class Reader>
  void Repair(Reader& reader, SimplexId x, std::span<const SimplexId> order, bool from_tetrahedra) {
    if (from_tetrahedra) {
      BuildFromTetrahedra(reader, x, order);
    } else {
      Build(reader, x, order);
    }
    Clear(x);
    PairStar(x);
  }

 private:
  // An edge, triangle or tetrahedron of the star before ranking, with its key in 64 bits: an
  // edge's is its other vertex's order; a triangle's its higher and lower edges' indices; a
  // tetrahedron's the index of its triangle on its two highest vertices, then its lowest edge's.
  struct Keyed {
    uint64_t key;
    SimplexId id;
    std::array<int32_t, 2> faces;  // a tetrahedron's other two triangles, by index
  };
  static uint64_t Pack(int32_t high, int32_t low) { return uint64_t(high) << 32 | uint32_t(low); }

  // A list of Keyed whose storage stays from star to star. Each is written field by field into
  // room made for a whole relation row (through push_back, a cell would go through a temporary
  // on the stack and a stalled reload, a large share of Build's time).
  class KeyedList {
   public:
    void Clear(size_t room) {
      if (items_.size() < room) items_.resize(room);
      size_ = 0;
    }
    void Add(uint64_t key, SimplexId id, int32_t face0 = -1, int32_t face1 = -1) {
      Keyed& k = items_[size_++];
      k.key = key;
      k.id = id;
      k.faces[0] = face0;
      k.faces[1] = face1;
    }
    size_t size() const { return size_; }
    bool empty() const { return size_ == 0; }
    const Keyed& operator[](size_t i) const { return items_[i]; }
    void SortByKey() {
      std::sort(items_.begin(), items_.begin() + ptrdiff_t(size_),
                [](const Keyed& a, const Keyed& b) { return a.key < b.key; });
    }
    // The index of `key`, which the list holds, once sorted; a search without branches.
    int32_t Find(uint64_t key) const {
      const Keyed* base = items_.data();
      size_t n = size_;
      while (n > 1) {
        const size_t half = n / 2;
        base = base[half].key <= key ? base + half : base;
        n -= half;
      }
      return int32_t(base - items_.data());
    }

   private:
    std::vector<Keyed> items_;
    size_t size_ = 0;
  };

  // Empties the lists for a new star of at most `edges` lower edges.
  void Begin(size_t edges) {
    edges_.Clear(edges);
    triangles_.Clear(0);
    tetrahedra_.Clear(0);
    upper_count_ = 0;
  }
  void AddEdge(SimplexId other_order, SimplexId e) { edges_.Add(uint64_t(other_order), e); }
  // Its vertices other than x by order, descending. Edges must be sorted.
  void AddTriangle(SimplexId o1, SimplexId o2, SimplexId f) {
    triangles_.Add(Pack(EdgeIndex(o1), EdgeIndex(o2)), f);
  }
  // As above; triangles must be sorted.
  void AddTetrahedron(SimplexId o1, SimplexId o2, SimplexId o3, SimplexId t) {
    const int32_t i1 = EdgeIndex(o1), i2 = EdgeIndex(o2), i3 = EdgeIndex(o3);
    tetrahedra_.Add(Pack(TriangleIndex(i1, i2), i3), t, TriangleIndex(i1, i3),
                    TriangleIndex(i2, i3));
  }
  int32_t EdgeIndex(SimplexId other_order) const { return edges_.Find(uint64_t(other_order)); }
  int32_t TriangleIndex(int32_t high, int32_t low) const {
    return triangles_.Find(Pack(high, low));
  }

  // Merges the sorted lists into cells_ by key. Among the cells whose highest other vertex is
  // edge i's, the edge comes first (padding is lowest); then each triangle (i, j) by ascending
  // j, followed by its tetrahedra (i, j, l) by ascending l. Every face of a cell has a lower
  // key, so its rank is known when the cell is placed.
  void Rank() {
    tetrahedra_.SortByKey();
    cells_.resize(edges_.size() + triangles_.size() + tetrahedra_.size());
    edge_rank_.resize(edges_.size());
    triangle_rank_.resize(triangles_.size());
    if (links_ != nullptr) triangle_index_.resize(cells_.size());
    size_t t = 0, q = 0;
    int32_t r = 0;
    for (size_t i = 0; i < edges_.size(); ++i) {
      edge_rank_[i] = r;
      cells_[r++] = {edges_[i].id, {-1, -1, -1}, 1, false};
      for (; t < triangles_.size() && triangles_[t].key >> 32 == i; ++t) {
        triangle_rank_[t] = r;
        if (links_ != nullptr) triangle_index_[r] = int32_t(t);
        const int32_t lower_edge = edge_rank_[uint32_t(triangles_[t].key)];
        cells_[r++] = {triangles_[t].id, {edge_rank_[i], lower_edge, -1}, 2, false};
        for (; q < tetrahedra_.size() && tetrahedra_[q].key >> 32 == t; ++q) {
          const Keyed& c = tetrahedra_[q];
          cells_[r++] = {
              c.id,
              {triangle_rank_[t], triangle_rank_[c.faces[0]], triangle_rank_[c.faces[1]]},
              3,
              false};
        }
      }
    }
  }

  void PairStar(SimplexId x) {
    if (edges_.empty()) {  // a minimum
      critical_[0].push_back(x);
      return;
    }
    IndexCofacets();
    const size_t n = cells_.size();
    zero_.Reset(n);
    one_.Reset(n);
    // The lowest cell is an edge (a cell's key is above its faces'), paired with x.
    Record(0, x, cells_[0].id);
    cells_[0].paired = true;
    for (size_t i = 1; i < edges_.size(); ++i) zero_.Insert(edge_rank_[i]);
    PushCofacets(0);
    while (!one_.empty() || !zero_.empty()) {
      while (!one_.empty()) {
        const int32_t alpha = one_.PopMin();
        int32_t face = -1;
        if (UnpairedFaces(alpha, face) == 0) {
          zero_.Insert(alpha);
        } else {
          Pair(face, alpha);
          PushCofacets(alpha);
          PushCofacets(face);
        }
      }
      while (!zero_.empty() && cells_[zero_.Min()].paired) zero_.PopMin();
      if (!zero_.empty()) {
        const int32_t gamma = zero_.PopMin();
        cells_[gamma].paired = true;  // critical
        critical_[cells_[gamma].dim].push_back(cells_[gamma].id);
        if (links_ != nullptr && cells_[gamma].dim == 2) RecordSaddle(gamma);
        PushCofacets(gamma);
      }
    }
  }

  template <class Reader>
  void Build(Reader& reader, SimplexId x, std::span<const SimplexId> order) {
    const SimplexId ox = order[x];
    const std::span<const SimplexId> star_edges = reader.vertex_edges(x);
    Begin(star_edges.size());
    for (SimplexId e : star_edges) {
      const auto [a, b] = reader.edge_vertices(e);
      const SimplexId oy = order[a == x ? b : a];
      if (oy < ox) AddEdge(oy, e);
    }
    edges_.SortByKey();
    // Fewer than two lower edges bound no lower triangle, fewer than three no tetrahedron.
    if (edges_.size() >= 2) {
      const std::span<const SimplexId> star_triangles = reader.vertex_triangles(x);
      triangles_.Clear(star_triangles.size());
      // The other vertices of a face are selected, not gathered in a loop: the orders stay in
      // registers (through an array on the stack they cost a stalled reload per face).
      for (SimplexId f : star_triangles) {
        const auto [a, b, c] = reader.triangle_vertices(f);
        const SimplexId op = order[a == x ? b : a], oq = order[c == x ? b : c];
        const SimplexId high = std::max(op, oq);
        if (high < ox) AddTriangle(high, std::min(op, oq), f);
      }
      triangles_.SortByKey();
    }
    // Links read the whole star: its first tetrahedron, and those around the lower triangles.
    const bool first = links_ != nullptr && !links_->first_tetrahedron.empty();
    if (triangles_.size() >= 3 || first || (links_ != nullptr && !triangles_.empty())) {
      const std::span<const SimplexId> star = reader.vertex_star(x);
      tetrahedra_.Clear(star.size());
      if (links_ != nullptr && upper_faces_.size() < star.size()) upper_faces_.resize(star.size());
      if (first) links_->first_tetrahedron[x] = FirstInInput(star);
      for (SimplexId t : star) {
        const auto v = reader.tetrahedron_vertices(t);
        // Descending by a sorting network; x's order comes first exactly when the rest are lower.
        SimplexId o0 = order[v[0]], o1 = order[v[1]], o2 = order[v[2]], o3 = order[v[3]];
        const auto descend = [](SimplexId& p, SimplexId& q) {
          const SimplexId high = std::max(p, q);
          q = std::min(p, q);
          p = high;
        };
        descend(o0, o1), descend(o2, o3), descend(o0, o2), descend(o1, o3), descend(o1, o2);
        if (o0 == ox) {
          AddTetrahedron(o1, o2, o3, t);  // a few of the star
        } else if (links_ != nullptr) {
          // With x second, its face on x and the two below is a lower triangle, next to which
          // the pairing does not see t (outside the lower star). Kept by that face's orders
          // (written always, kept when x is second: no branch to mispredict); looked up only
          // for the few triangles whose lower cofacets are not all their tetrahedra.
          upper_faces_[upper_count_] = {Pack(o2, o3), t};
          upper_count_ += o1 == ox;
        }
      }
    }
    Rank();
  }

  // Build's star from x's tetrahedra alone. Its lower edges and triangles are the vertices and
  // vertex pairs below x of its lower tetrahedra and of the other tetrahedra of its star; their
  // ids come from the static encoding.
  template <class Reader>
  void BuildFromTetrahedra(Reader& reader, SimplexId x, std::span<const SimplexId> order) {
    const SimplexId ox = order[x];
    below_.clear();
    pairs_below_.clear();
    lower_tetrahedra_.clear();
    const auto before = [&](SimplexId a, SimplexId b) { return order[a] > order[b]; };
    for (SimplexId t : reader.vertex_star(x)) {
      std::array<SimplexId, 3> lower;  // the vertices below x, descending by order
      int n = 0;
      for (SimplexId w : reader.tetrahedron_vertices(t)) {
        if (w != x && order[w] < ox) lower[n++] = w;
      }
      if (n == 0) continue;
      if (n >= 2 && before(lower[1], lower[0])) std::swap(lower[0], lower[1]);
      if (n == 3) {
        if (before(lower[2], lower[1])) std::swap(lower[1], lower[2]);
        if (before(lower[1], lower[0])) std::swap(lower[0], lower[1]);
        lower_tetrahedra_.push_back({order[lower[0]], order[lower[1]], order[lower[2]], t});
      }
      for (int i = 0; i < n; ++i) {
        below_.push_back(lower[i]);
        for (int j = i + 1; j < n; ++j) pairs_below_.push_back({lower[i], lower[j]});
      }
    }
    std::sort(below_.begin(), below_.end());
    below_.erase(std::unique(below_.begin(), below_.end()), below_.end());
    Begin(below_.size());
    for (SimplexId y : below_) {
      AddEdge(order[y], topology_.FindEdge(std::min(x, y), std::max(x, y)));
    }
    edges_.SortByKey();
    std::sort(pairs_below_.begin(), pairs_below_.end());
    pairs_below_.erase(std::unique(pairs_below_.begin(), pairs_below_.end()), pairs_below_.end());
    triangles_.Clear(pairs_below_.size());
    for (const auto& [y, z] : pairs_below_) {  // order[y] > order[z]
      SimplexId ids[3] = {x, y, z};
      SortVertexIds(ids, 3);
      AddTriangle(order[y], order[z], topology_.FindTriangle(ids[0], ids[1], ids[2]));
    }
    triangles_.SortByKey();
    tetrahedra_.Clear(lower_tetrahedra_.size());
    for (const auto& [o1, o2, o3, t] : lower_tetrahedra_) AddTetrahedron(o1, o2, o3, t);
    Rank();
  }

  // Unpaired faces of a triangle or tetrahedron; `face` gets the last one found.
  int UnpairedFaces(int32_t rank, int32_t& face) const {
    const StarCell& c = cells_[rank];
    int count = 0;
    for (int i = 0; i < c.dim; ++i) {
      if (!cells_[c.faces[i]].paired) {
        ++count;
        face = c.faces[i];
      }
    }
    return count;
  }

  // For the edges and triangles of the star, their cofacets there (ascending rank), as CSR:
  // cofacets_[cofacet_begin_[r] ..] for the cell of rank r.
  void IndexCofacets() {
    const size_t n = cells_.size();
    cofacet_begin_.assign(n + 1, 0);
    for (const StarCell& c : cells_) {
      if (c.dim == 1) continue;
      for (int i = 0; i < c.dim; ++i) ++cofacet_begin_[c.faces[i] + 1];
    }
    for (size_t r = 1; r <= n; ++r) cofacet_begin_[r] += cofacet_begin_[r - 1];
    cofacets_.resize(cofacet_begin_[n]);
    cursor_.assign(cofacet_begin_.begin(), cofacet_begin_.end() - 1);
    for (size_t r = 0; r < n; ++r) {
      const StarCell& c = cells_[r];
      if (c.dim == 1) continue;
      for (int i = 0; i < c.dim; ++i) cofacets_[cursor_[c.faces[i]]++] = int32_t(r);
    }
  }

  // Queues (PQone) the cofacets of a cell that have exactly one unpaired face.
  void PushCofacets(int32_t rank) {
    for (int32_t k = cofacet_begin_[rank]; k < cofacet_begin_[rank + 1]; ++k) {
      int32_t face;
      if (UnpairedFaces(cofacets_[k], face) == 1) one_.Insert(cofacets_[k]);
    }
  }

  // Forgets the pairings of x and of its star's cells.
  void Clear(SimplexId x) {
    if (!gradient_.up[0].empty()) gradient_.up[0][x] = -1;
    for (const StarCell& c : cells_) {
      Pairings& up = gradient_.up[c.dim];
      Pairings& down = gradient_.down[c.dim];
      if (!up.empty()) up[c.id] = -1;
      if (!down.empty()) down[c.id] = -1;
    }
  }

  // Pairs two cells of the star, by rank.
  void Pair(int32_t lower, int32_t higher) {
    StarCell& alpha = cells_[lower];
    StarCell& beta = cells_[higher];
    Record(alpha.dim, alpha.id, beta.id);
    alpha.paired = true;
    beta.paired = true;
    if (links_ != nullptr && alpha.dim == 2) {
      SimplexId other[2];
      links_->up[beta.id] = TriangleTetrahedra(lower, higher, other) == 1 ? other[0] : -1;
    }
  }

  // The star's tetrahedron first in input order (-1 when empty).
  SimplexId FirstInInput(std::span<const SimplexId> star) const {
    SimplexId first = -1, first_input = 0;
    for (SimplexId t : star) {
      const SimplexId input = topology_.tetrahedron_input_id(t);
      if (first < 0 || input < first_input) {
        first = t;
        first_input = input;
      }
    }
    return first;
  }

  // The tetrahedra of the star's triangle of rank `triangle` but the one of rank `except` (-1:
  // none), into `out`; returns how many: its cofacets in the lower star, then those outside it
  // (a triangle has two tetrahedra at most: no crowded triangles).
  int TriangleTetrahedra(int32_t triangle, int32_t except, SimplexId out[2]) const {
    int n = 0, found = 0;  // found: `except` too
    for (int32_t k = cofacet_begin_[triangle]; k < cofacet_begin_[triangle + 1]; ++k, ++found) {
      if (cofacets_[k] != except) out[n++] = cells_[cofacets_[k]].id;
    }
    if (found == 2) return n;
    // The triangle's other two vertices' orders, higher first, from its two edges' keys.
    const uint64_t edges = triangles_[triangle_index_[triangle]].key;
    const uint64_t key =
        Pack(SimplexId(edges_[edges >> 32].key), SimplexId(edges_[uint32_t(edges)].key));
    for (size_t i = 0; i < upper_count_; ++i) {
      const auto& [face, t] = upper_faces_[i];
      if (face == key) {
        out[n++] = t;
        if (++found == 2) break;
      }
    }
    return n;
  }

  // A critical triangle of the star and its tetrahedra, ascending, into links_->saddles.
  void RecordSaddle(int32_t triangle) {
    SimplexId tets[2] = {-1, -1};
    const int n = TriangleTetrahedra(triangle, -1, tets);
    if (n == 2 && tets[1] < tets[0]) std::swap(tets[0], tets[1]);
    links_->saddles[consumer_].push_back({cells_[triangle].id, tets[0], tets[1]});
  }
  // Writes the pair (d-cell lower, (d + 1)-cell higher) into the gradient.
  void Record(int d, SimplexId lower, SimplexId higher) {
    ++pairs_[d];
    // An empty array is one the caller does not keep (GradientArrays).
    if (!gradient_.up[d].empty()) gradient_.up[d][lower] = higher;
    if (!gradient_.down[d + 1].empty()) gradient_.down[d + 1][higher] = lower;
  }

  GradientField& gradient_;
  const Topology& topology_;
  std::array<std::vector<SimplexId>, 4> critical_;
  std::array<int64_t, 3> pairs_{};
  KeyedList edges_, triangles_, tetrahedra_;        // the star being built, sorted by key
  std::vector<int32_t> edge_rank_, triangle_rank_;  // by index in edges_, triangles_
  std::vector<StarCell> cells_;                     // by rank
  std::vector<int32_t> cofacet_begin_, cofacets_, cursor_;
  RankSet zero_, one_;
  // BuildFromTetrahedra's scratch: the vertices below x, the pairs of them in a tetrahedron, and
  // the lower tetrahedra (their other vertices' orders, descending, then their id).
  std::vector<SimplexId> below_;
  std::vector<std::pair<SimplexId, SimplexId>> pairs_below_;
  std::vector<std::array<SimplexId, 4>> lower_tetrahedra_;
  // RecordLinks's: where to record, as which consumer.
  AscendingLinks* links_ = nullptr;
  int consumer_ = 0;
  // The star's tetrahedra outside the lower star with x second in order: (their face on x and
  // the two vertices below it, as Pack(higher order, lower order); the tetrahedron). And per
  // rank, a triangle's index in triangles_.
  std::vector<std::pair<uint64_t, SimplexId>> upper_faces_;  // the first upper_count_
  size_t upper_count_ = 0;
  std::vector<int32_t> triangle_index_;
};

}  // namespace

void CellVertices(const Topology& topology, int d, SimplexId c, SimplexId* ids) {
  switch (d) {
    case 0: ids[0] = c; break;
    case 1: std::copy_n(topology.edge(c).begin(), 2, ids); break;
    case 2: std::copy_n(topology.triangle(c).begin(), 3, ids); break;
    default: std::copy_n(topology.tetrahedron(c).begin(), 4, ids); break;
  }
}

void CellTokens(const Topology& topology, int d, SimplexId c, SimplexId* ids) {
  CellVertices(topology, d, c, ids);
  for (int i = 0; i <= d; ++i) ids[i] = topology.vertex_input_id(ids[i]);
  SortVertexIds(ids, d + 1);
}

namespace {

char* WriteIds(char* p, const DecimalTable& decimal, const SimplexId* ids, int n) {
  for (int i = 0; i < n; ++i) {
    if (i > 0) *p++ = ',';
    p = decimal.Write(p, uint32_t(ids[i]));
  }
  return p;
}

// The input vertex ids of `cofacet`, a (d + 1)-cell having the d-cell of input ids `ids` as a
// face, ascending, into out[0..d + 1]. Only the vertex not in `ids` is looked for, highest first
// (the stored vertex of a triangle or an edge, which is most often the one).
void CofacetTokens(const Topology& topology, int d, const SimplexId* ids, SimplexId cofacet,
                   SimplexId* out) {
  const auto in_face = [&](SimplexId internal) {
    const SimplexId input = topology.vertex_input_id(internal);
    return std::find(ids, ids + d + 1, input) != ids + d + 1 ? -1 : input;
  };
  SimplexId extra = -1;
  switch (d) {
    case 0: {
      const auto [a, b] = topology.edge(cofacet);
      extra = in_face(b);
      if (extra < 0) extra = in_face(a);
      break;
    }
    case 1: {
      const auto [a, b, c] = topology.triangle(cofacet);
      extra = in_face(c);
      if (extra < 0) extra = in_face(b);
      if (extra < 0) extra = in_face(a);
      break;
    }
    default:
      for (SimplexId v : topology.tetrahedron(cofacet)) {
        if (extra < 0) extra = in_face(v);
      }
  }
  // Insert `extra` into the sorted ids.
  int k = 0;
  for (int i = 0; i <= d; ++i) {
    if (extra >= 0 && extra < ids[i]) out[k++] = std::exchange(extra, -1);
    out[k++] = ids[i];
  }
  if (extra >= 0) out[k] = extra;
}

// Appends "<d> <cell>[ <higher cell>]" (a line of the critical-cell or pair digests); `ids` are
// the cell's input vertex ids, ascending.
void AppendCellLine(std::string& line, const Topology& topology, const DecimalTable& decimal, int d,
                    const SimplexId* ids, SimplexId higher = -1) {
  char buffer[2 + 4 * 11 + 1 + 4 * 11 + 8];  // + 8: DecimalTable::Write's slack
  char* p = buffer;
  *p++ = char('0' + d);
  *p++ = ' ';
  p = WriteIds(p, decimal, ids, d + 1);
  if (higher >= 0) {
    *p++ = ' ';
    SimplexId higher_ids[4];
    CofacetTokens(topology, d, ids, higher, higher_ids);
    p = WriteIds(p, decimal, higher_ids, d + 2);
  }
  line.append(buffer, p);
}

}  // namespace

std::string DiscreteGradientResult::CriticalCellsDigest(const Topology& topology) const {
  const DecimalTable decimal(topology.num_vertices());
  std::vector<LineGroup> groups;
  for (int d = 0; d < 4; ++d) {
    const std::vector<SimplexId>& cells = critical[d];
    groups.push_back(
        LineGroup{.items = int64_t(cells.size()),
                  .tokens = d + 1,
                  .sort_tokens =
                      [&topology, &cells, d](int64_t i, SimplexId* ids) {
                        CellTokens(topology, d, cells[i], ids);
                        return true;
                      },
                  .append_line =
                      [&topology, &decimal, d](int64_t, const SimplexId* ids, std::string& line) {
                        AppendCellLine(line, topology, decimal, d, ids);
                      }});
  }
  return SortedLinesSha256(topology.num_vertices(), groups);
}

std::string DiscreteGradientResult::PairsDigest(const Topology& topology) const {
  const DecimalTable decimal(topology.num_vertices());
  std::vector<LineGroup> groups;
  for (int d = 0; d < 3; ++d) {
    if (gradient.up[d].empty()) {
      // GradientArrays::kPersistence: triangle -> tetrahedron pairs are read from down[3].
      groups.push_back(LineGroup{
          .items = topology.num_simplices(d + 1),
          .tokens = d + 1,
          .sort_tokens =
              [this, &topology, d](int64_t c, SimplexId* ids) {
                if (gradient.down[d + 1][c] < 0) return false;
                CellTokens(topology, d, gradient.down[d + 1][c], ids);
                return true;
              },
          .append_line =
              [&topology, &decimal, d](int64_t c, const SimplexId* ids, std::string& line) {
                AppendCellLine(line, topology, decimal, d, ids, SimplexId(c));
              }});
      continue;
    }
    groups.push_back(LineGroup{
        .items = topology.num_simplices(d),
        .tokens = d + 1,
        .sort_tokens =
            [this, &topology, d](int64_t c, SimplexId* ids) {
              if (gradient.up[d][c] < 0) return false;
              CellTokens(topology, d, SimplexId(c), ids);
              return true;
            },
        .append_line =
            [this, &topology, &decimal, d](int64_t c, const SimplexId* ids, std::string& line) {
              AppendCellLine(line, topology, decimal, d, ids, gradient.up[d][c]);
            }});
  }
  return SortedLinesSha256(topology.num_vertices(), groups);
}

absl::StatusOr<std::vector<SimplexId>> SaddleTetrahedra(const AscendingLinks& links,
                                                        std::span<const SimplexId> saddles) {
  // The sweep met each 2-saddle once, in its highest vertex's lower star.
  std::vector<std::array<SimplexId, 3>> met;
  met.reserve(saddles.size());
  for (const auto& per_consumer : links.saddles) {
    met.insert(met.end(), per_consumer.begin(), per_consumer.end());
  }
  std::sort(met.begin(), met.end());
  if (met.size() != saddles.size() ||
      !std::equal(met.begin(), met.end(), saddles.begin(),
                  [](const std::array<SimplexId, 3>& m, SimplexId f) { return m[0] == f; })) {
    return absl::InternalError(absl::StrCat("the gradient's sweep recorded ", met.size(),
                                            " 2-saddles, not the ", saddles.size(), " it found"));
  }
  std::vector<SimplexId> tets(2 * met.size());
  for (size_t i = 0; i < met.size(); ++i) {
    tets[2 * i] = met[i][1];
    tets[2 * i + 1] = met[i][2];
  }
  return tets;
}

RelationSet DiscreteGradientDeclared() { return {Relation::kVE, Relation::kVF, Relation::kVT}; }

template <TopologicalStructure Structure>
absl::StatusOr<DiscreteGradientResult> RunDiscreteGradient(
    Structure& structure, std::span<const SimplexId> order, const RunContext& context,
    GradientArrays arrays, VertexNeighbors* neighbors, AscendingLinks* links) {
  const Topology& topo = structure.topology();
  DiscreteGradientResult result;
  GradientField& g = result.gradient;
  const bool all = arrays == GradientArrays::kAll;
  const auto unpaired = [&](Pairings& a, int d) {
    a.resize(size_t(topo.num_simplices(d)));
    ParallelForRanges(
        int64_t(a.size()), 1 << 16, std::max(context.consumers, 1),
        [&](int64_t begin, int64_t end) { std::fill(a.begin() + begin, a.begin() + end, -1); });
  };
  for (int d = 0; d < 3; ++d) {
    if (all || d < 2) unpaired(g.up[d], d);
  }
  for (int d = 1; d < 4; ++d) {
    if (all || (d == 3 && arrays == GradientArrays::kPersistence)) unpaired(g.down[d], d);
  }
  // Every cell lies in the lower star of exactly one vertex (its highest), so consumers on
  // different blocks write disjoint entries. Each counts what it pairs and lists what it leaves
  // critical, so no pass over every cell follows. Blocks go out in runs to whichever consumer
  // is free: a block's cost depends on the structure (on actopo, on what its producers had
  // ready), so equal halves would leave one consumer well behind the other.
  const int consumers = std::max(context.consumers, 1);
  std::vector<std::array<std::vector<SimplexId>, 4>> critical(consumers);
  std::vector<std::array<int64_t, 3>> pairs(consumers);
  const absl::Status status = RunOnConsumersShared(
      context, topo.num_blocks(), std::max(1, topo.num_blocks() / (16 * consumers)),
      [&](int consumer, ItemQueue& queue, WorkTracker& tracker) {
        auto reader = structure.NewReader();
        LowerStarPairing pairing(g, topo);
        if (links != nullptr) pairing.RecordLinks(links, consumer);
        int64_t begin, end;
        while (queue.Next(begin, end)) {
          for (int32_t b = int32_t(begin); b < int32_t(end); ++b) {
            for (SimplexId v = topo.block_vertex_begin(b); v < topo.block_vertex_begin(b + 1);
                 ++v) {
              pairing.Process(reader, v, order);
            }
            if (neighbors != nullptr) neighbors->FillBlock(b, reader);
            reader.Finished(b);  // a star reads its own block only, and no block comes twice
          }
          if (!tracker.Done(end - begin)) break;
        }
        critical[consumer] = std::move(pairing.critical());
        pairs[consumer] = pairing.pairs();
      });
  if (!status.ok()) return status;
  for (size_t c = 0; c < critical.size(); ++c) {
    for (int d = 0; d < 4; ++d) {
      result.critical[d].insert(result.critical[d].end(), critical[c][d].begin(),
                                critical[c][d].end());
      if (d < 3) result.pairs[d] += pairs[c][d];
    }
  }
  for (int d = 0; d < 4; ++d) {
    std::sort(result.critical[d].begin(), result.critical[d].end());
    result.critical_cells[d] = int64_t(result.critical[d].size());
  }
  return result;
}

namespace {

// The vertex of cell (d, c) that comes last in `order`: the vertex whose lower star holds it.
SimplexId HighestVertex(const Topology& topo, int d, SimplexId c,
                        std::span<const SimplexId> order) {
  SimplexId ids[4];
  CellVertices(topo, d, c, ids);
  return *std::max_element(ids, ids + d + 1,
                           [&](SimplexId a, SimplexId b) { return order[a] < order[b]; });
}

// Where each block's vertices start in `vertices` (ascending): (block, first index) per block
// holding any, then (-1, size).
std::vector<std::pair<int32_t, size_t>> BlockRuns(const Topology& topo,
                                                  std::span<const SimplexId> vertices) {
  std::vector<std::pair<int32_t, size_t>> runs;
  for (size_t i = 0; i < vertices.size(); ++i) {
    const int32_t b = topo.vertex_block(vertices[i]);
    if (runs.empty() || runs.back().first != b) runs.emplace_back(b, i);
  }
  runs.emplace_back(-1, vertices.size());
  return runs;
}

// Per consumer, each block of `vertices` (ascending) in turn, whole blocks to whichever consumer
// is free: visit(consumer, reader, v) for each vertex. Visits read their vertex's block only:
// the reader is done with a block once its vertices are visited.
template <class Structure, class Visit>
absl::Status ForEachVertexByBlock(Structure& structure, std::span<const SimplexId> vertices,
                                  const RunContext& context, Visit&& visit) {
  const auto runs = BlockRuns(structure.topology(), vertices);
  return RunOnConsumersShared(context, int64_t(runs.size()) - 1, /*chunk=*/1,
                              [&](int consumer, ItemQueue& queue, WorkTracker& tracker) {
                                auto reader = structure.NewReader();
                                int64_t begin, end;
                                while (queue.Next(begin, end)) {
                                  for (int64_t r = begin; r < end; ++r) {
                                    for (size_t i = runs[r].second; i < runs[r + 1].second; ++i) {
                                      visit(consumer, reader, vertices[i]);
                                    }
                                    reader.Finished(runs[r].first);
                                  }
                                  if (!tracker.Done(end - begin)) return;
                                }
                              });
}

}  // namespace

template <TopologicalStructure Structure>
absl::StatusOr<DiscreteGradientResult> UpdateDiscreteGradient(Structure& structure,
                                                              DiscreteGradientResult previous,
                                                              std::span<const SimplexId> order,
                                                              std::span<const SimplexId> reordered,
                                                              const RunContext& context,
                                                              std::span<const SimplexId> changed) {
  Trace::Scope span(context.trace.get(), "gradient update", "phase");
  const Topology& topo = structure.topology();
  const int consumers = std::max(context.consumers, 1);
  DiscreteGradientResult result = std::move(previous);
  GradientField& g = result.gradient;

  // The lower stars that can change: those of the reordered vertices and of their neighbours
  // (or the caller's `changed`, a subset). Any other vertex's star holds no reordered vertex,
  // so its vertices compare as before.
  std::vector<SimplexId> dirty;
  if (!changed.empty()) {
    dirty.assign(changed.begin(), changed.end());
  } else {
    std::vector<SimplexId> moved(reordered.begin(), reordered.end());
    std::sort(moved.begin(), moved.end());
    moved.erase(std::unique(moved.begin(), moved.end()), moved.end());
    std::vector<std::vector<SimplexId>> found(consumers);
    RunContext quiet = context;
    quiet.progress = nullptr;
    RETURN_IF_ERROR(
        ForEachVertexByBlock(structure, moved, quiet, [&](int consumer, auto& reader, SimplexId v) {
          found[consumer].push_back(v);
          for (SimplexId e : reader.vertex_edges(v)) {
            const auto ev = reader.edge_vertices(e);
            found[consumer].push_back(ev[0] == v ? ev[1] : ev[0]);
          }
        }));
    for (const auto& list : found) dirty.insert(dirty.end(), list.begin(), list.end());
    std::sort(dirty.begin(), dirty.end());
    dirty.erase(std::unique(dirty.begin(), dirty.end()), dirty.end());
  }

  // Their lower stars paired again, as RunDiscreteGradient pairs every star. A cell's highest
  // vertex is dirty in both orders or in neither (when it differs, each of the two has the other
  // below it in one order only), so every cell whose pairing may change is cleared and paired
  // here, and no other is touched.
  std::vector<std::array<std::vector<SimplexId>, 4>> critical(consumers);
  // Localized structures read only VT (LowerStarPairing::Repair), of the dirty stars' blocks: a
  // sparse subset in ascending order, where prefetching the next blocks' declared relations
  // computes VE and VF nobody reads, and VT of blocks no dirty star lies in.
  constexpr bool kFromTetrahedra = !Structure::kRelationsInPlace;
  std::vector<std::optional<LowerStarPairing>> pairings(consumers);
  PrefetchOff<Structure> off(structure);
  RETURN_IF_ERROR(
      ForEachVertexByBlock(structure, dirty, context, [&](int consumer, auto& reader, SimplexId v) {
        if (!pairings[consumer]) pairings[consumer].emplace(g, topo);
        pairings[consumer]->Repair(reader, v, order, kFromTetrahedra);
      }));
  for (int c = 0; c < consumers; ++c) {
    if (pairings[c]) critical[c] = std::move(pairings[c]->critical());
  }

  // The critical cells: those of clean stars, kept, and the dirty stars' new ones.
  for (int d = 0; d < 4; ++d) {
    std::vector<SimplexId>& cells = result.critical[d];
    std::erase_if(cells, [&](SimplexId c) {
      return std::binary_search(dirty.begin(), dirty.end(), HighestVertex(topo, d, c, order));
    });
    for (const auto& per_consumer : critical) {
      cells.insert(cells.end(), per_consumer[d].begin(), per_consumer[d].end());
    }
    std::sort(cells.begin(), cells.end());
    result.critical_cells[d] = int64_t(cells.size());
  }
  // Every cell is critical or in one pair: the pairs of each dimension follow from the counts.
  result.pairs[0] = topo.num_vertices() - result.critical_cells[0];
  result.pairs[1] = topo.num_edges() - result.critical_cells[1] - result.pairs[0];
  result.pairs[2] = topo.num_triangles() - result.critical_cells[2] - result.pairs[1];
  return result;
}

#define ACTOPO_INSTANTIATE(S)                                                             \
  template absl::StatusOr<DiscreteGradientResult> UpdateDiscreteGradient(                 \
      S&, DiscreteGradientResult, std::span<const SimplexId>, std::span<const SimplexId>, \
      const RunContext&, std::span<const SimplexId>);
ACTOPO_FOR_EACH_STRUCTURE(ACTOPO_INSTANTIATE)
#undef ACTOPO_INSTANTIATE

#define ACTOPO_INSTANTIATE(S)                                                              \
  template absl::StatusOr<DiscreteGradientResult> RunDiscreteGradient(                     \
      S&, std::span<const SimplexId>, const RunContext&, GradientArrays, VertexNeighbors*, \
      AscendingLinks*);
ACTOPO_FOR_EACH_STRUCTURE(ACTOPO_INSTANTIATE)
#undef ACTOPO_INSTANTIATE

}  // namespace actopo
