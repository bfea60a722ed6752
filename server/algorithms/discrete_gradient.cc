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

namespace actopo {
namespace {

using Uint128 = unsigned __int128;

// A cell of a vertex x's lower star. `key` holds the orders of its vertices other than x,
// descending, padded with -1: cells compare by key, across dimensions too.
struct StarCell {
  int dim;
  SimplexId id;
  std::array<SimplexId, 3> key;
  std::array<int32_t, 3> faces;  // indices in the lower star of its faces that contain x
  bool paired;
  int32_t rank = 0;  // position among the star's edges, triangles and tetrahedra by key
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

  // The same for a gradient being updated to a new order: first forgets what the gradient held
  // for the star's cells (critical cells are left unwritten). With `from_tetrahedra`, the star is
  // read from VT alone and the static encoding's lookups (FindEdge, FindTriangle), for structures
  // that compute relations by block: an update pairs a few stars of each block it visits
  // (part_5M.vtu at 1%: 50k stars in 1,786 blocks, 12% of their vertices), and a block's VE and
  // VF cost more than its VT. There the update took 0.42 s on actopo, 0.25 s from VT alone;
  // explicit, which holds VE and VF, stays faster reading them (0.17 s against 0.20 s).
  template <class Reader>
  void Repair(Reader& reader, SimplexId x, std::span<const SimplexId> order, bool from_tetrahedra) {
    if (from_tetrahedra) {
      BuildFromTetrahedra(reader, x, order);
    } else {
      Build(reader, x, order);
    }
    Clear();
    PairStar(x);
  }

 private:
  void PairStar(SimplexId x) {
    auto& edges = star_[1];
    if (edges.empty()) {  // a minimum
      critical_[0].push_back(x);
      return;
    }
    IndexCofacets();
    RankCells();
    zero_.Reset(ranked_.size());
    one_.Reset(ranked_.size());
    // The lowest cell is an edge: a cell's key is above its faces'.
    StarCell& delta = Ranked(0);
    Pair(star_[0][0], delta);
    for (const StarCell& e : edges) {
      if (!e.paired) zero_.Insert(e.rank);
    }
    PushCofacets(delta);
    while (!one_.empty() || !zero_.empty()) {
      while (!one_.empty()) {
        StarCell& alpha = Ranked(one_.PopMin());
        int face = -1;
        if (UnpairedFaces(alpha, face) == 0) {
          zero_.Insert(alpha.rank);
        } else {
          StarCell& beta = star_[alpha.dim - 1][face];
          Pair(beta, alpha);
          PushCofacets(alpha);
          PushCofacets(beta);
        }
      }
      while (!zero_.empty() && Ranked(zero_.Min()).paired) zero_.PopMin();
      if (!zero_.empty()) {
        StarCell& gamma = Ranked(zero_.PopMin());
        gamma.paired = true;  // critical
        critical_[gamma.dim].push_back(gamma.id);
        PushCofacets(gamma);
      }
    }
  }

  // Ranks the edges, triangles and tetrahedra of the star by key: each key (orders + 1, so the
  // padding -1 is 0) and the cell's place in 128 bits, sorted as integers.
  void RankCells() {
    ranked_.clear();
    for (int d = 1; d <= 3; ++d) {
      for (size_t i = 0; i < star_[d].size(); ++i) {
        const auto& k = star_[d][i].key;
        ranked_.push_back(Uint128(uint32_t(k[0] + 1)) << 96 | Uint128(uint32_t(k[1] + 1)) << 64 |
                          Uint128(uint32_t(k[2] + 1)) << 32 | uint32_t(i << 2 | d));
      }
    }
    std::sort(ranked_.begin(), ranked_.end());
    for (size_t r = 0; r < ranked_.size(); ++r) Ranked(int32_t(r)).rank = int32_t(r);
  }
  // The cell of a rank (once RankCells ran).
  StarCell& Ranked(int32_t rank) {
    const uint32_t place = uint32_t(ranked_[rank]);
    return star_[place & 3][place >> 2];
  }

  template <class Reader>
  void Build(Reader& reader, SimplexId x, std::span<const SimplexId> order) {
    for (auto& s : star_) s.clear();
    const SimplexId ox = order[x];
    star_[0].push_back({0, x, {-1, -1, -1}, {}, false});
    for (SimplexId e : reader.vertex_edges(x)) {
      const auto [a, b] = reader.edge_vertices(e);
      const SimplexId oy = order[a == x ? b : a];
      if (oy < ox) star_[1].push_back({1, e, {oy, -1, -1}, {}, false});
    }
    if (star_[1].size() < 2) return;
    // The other vertices of a face are selected, not gathered in a loop: the orders stay in
    // registers (through an array on the stack they cost a stalled reload per face).
    for (SimplexId f : reader.vertex_triangles(x)) {
      const auto [a, b, c] = reader.triangle_vertices(f);
      const SimplexId op = order[a == x ? b : a], oq = order[c == x ? b : c];
      const SimplexId high = std::max(op, oq);
      if (high > ox) continue;
      StarCell cell{2, f, {high, std::min(op, oq), -1}, {}, false};
      IndexTriangleFaces(cell);
      star_[2].push_back(cell);
    }
    if (star_[2].size() < 3) return;
    for (SimplexId t : reader.vertex_star(x)) {
      const auto v = reader.tetrahedron_vertices(t);
      // Descending by a sorting network; x's order comes first exactly when the rest are lower.
      SimplexId o0 = order[v[0]], o1 = order[v[1]], o2 = order[v[2]], o3 = order[v[3]];
      const auto descend = [](SimplexId& p, SimplexId& q) {
        const SimplexId high = std::max(p, q);
        q = std::min(p, q);
        p = high;
      };
      descend(o0, o1), descend(o2, o3), descend(o0, o2), descend(o1, o3), descend(o1, o2);
      if (o0 != ox) continue;  // most of the star
      StarCell cell{3, t, {o1, o2, o3}, {}, false};
      IndexTetrahedronFaces(cell);
      star_[3].push_back(cell);
    }
  }

  // Build's star from x's tetrahedra alone. Its lower edges and triangles are the vertices and
  // vertex pairs below x of its lower tetrahedra and of the other tetrahedra of its star; their
  // ids come from the static encoding. Cells come in another order than Build's, which changes
  // nothing: keys are distinct, and the pairing picks cells by key.
  template <class Reader>
  void BuildFromTetrahedra(Reader& reader, SimplexId x, std::span<const SimplexId> order) {
    for (auto& s : star_) s.clear();
    const SimplexId ox = order[x];
    star_[0].push_back({0, x, {-1, -1, -1}, {}, false});
    below_.clear();
    pairs_below_.clear();
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
        std::array<SimplexId, 3> key{order[lower[0]], order[lower[1]], order[lower[2]]};
        star_[3].push_back({3, t, key, {}, false});
      }
      for (int i = 0; i < n; ++i) {
        below_.push_back(lower[i]);
        for (int j = i + 1; j < n; ++j) pairs_below_.push_back({lower[i], lower[j]});
      }
    }
    std::sort(below_.begin(), below_.end());
    below_.erase(std::unique(below_.begin(), below_.end()), below_.end());
    for (SimplexId y : below_) {
      star_[1].push_back(
          {1, topology_.FindEdge(std::min(x, y), std::max(x, y)), {order[y], -1, -1}, {}, false});
    }
    if (star_[1].size() < 2) return;  // then no lower triangle or tetrahedron either
    std::sort(pairs_below_.begin(), pairs_below_.end());
    pairs_below_.erase(std::unique(pairs_below_.begin(), pairs_below_.end()), pairs_below_.end());
    for (const auto& [y, z] : pairs_below_) {
      SimplexId ids[3] = {x, y, z};
      SortVertexIds(ids, 3);
      StarCell cell{
          2, topology_.FindTriangle(ids[0], ids[1], ids[2]), {order[y], order[z], -1}, {}, false};
      IndexTriangleFaces(cell);
      star_[2].push_back(cell);
    }
    for (StarCell& cell : star_[3]) IndexTetrahedronFaces(cell);
  }

  // A lower triangle's two edges that contain x, as indices in star_[1]. Without a branch per
  // candidate: each index is written to the next slot, which only a match keeps (the match is
  // unpredictable; as a branch it cost a fifth of Build, perf on wavelet128).
  void IndexTriangleFaces(StarCell& cell) {
    int32_t found[3] = {-1, -1, -1};  // the third slot takes the writes after both matches
    int k = 0;
    for (size_t j = 0; j < star_[1].size(); ++j) {
      const SimplexId y = star_[1][j].key[0];
      found[k] = int32_t(j);
      k += int(y == cell.key[0]) + int(y == cell.key[1]);  // the two orders differ
      k -= k == 3;  // never with a valid star: two edges match
    }
    cell.faces = {found[0], found[1], -1};
  }

  // A lower tetrahedron's three faces that contain x, as indices in star_[2]; as above.
  void IndexTetrahedronFaces(StarCell& cell) {
    const auto& key = cell.key;
    int32_t found[4] = {-1, -1, -1, -1};
    int k = 0;
    for (size_t j = 0; j < star_[2].size(); ++j) {
      const auto& fk = star_[2][j].key;
      found[k] = int32_t(j);
      k += int(fk[0] == key[0] && (fk[1] == key[1] || fk[1] == key[2])) +
           int(fk[0] == key[1] && fk[1] == key[2]);  // key[0] != key[1]: one at most
      k -= k == 4;                                   // never with a valid star: three faces match
    }
    cell.faces = {found[0], found[1], found[2]};
  }

  // Unpaired faces of a 2- or 3-cell inside the lower star; `face` gets the last one found.
  int UnpairedFaces(const StarCell& c, int& face) const {
    const int n = c.dim == 2 ? 2 : 3;
    int count = 0;
    for (int i = 0; i < n; ++i) {
      if (!star_[c.dim - 1][c.faces[i]].paired) {
        ++count;
        face = c.faces[i];
      }
    }
    return count;
  }

  // For the edges and triangles of the lower star, their cofacets there (ascending index), as
  // CSR: cofacets_[d][cofacet_begin_[d][i] ..] for cell i of dimension d.
  void IndexCofacets() {
    for (int d = 1; d <= 2; ++d) {
      std::vector<int32_t>& begin = cofacet_begin_[d];
      std::vector<int32_t>& list = cofacets_[d];
      begin.assign(star_[d].size() + 1, 0);
      for (const StarCell& c : star_[d + 1]) {
        for (int i = 0; i <= d; ++i) ++begin[c.faces[i] + 1];
      }
      for (size_t i = 1; i < begin.size(); ++i) begin[i] += begin[i - 1];
      list.resize(begin.back());
      cursor_.assign(begin.begin(), begin.end() - 1);
      for (size_t j = 0; j < star_[d + 1].size(); ++j) {
        for (int i = 0; i <= d; ++i) list[cursor_[star_[d + 1][j].faces[i]]++] = int32_t(j);
      }
    }
  }

  // Queues (PQone) the cofacets of a cell that have exactly one unpaired face.
  void PushCofacets(const StarCell& cell) {
    const int dim = cell.dim;
    if (dim != 1 && dim != 2) return;
    const int32_t index = int32_t(&cell - star_[dim].data());
    const std::vector<int32_t>& begin = cofacet_begin_[dim];
    for (int32_t k = begin[index]; k < begin[index + 1]; ++k) {
      const StarCell& cofacet = star_[dim + 1][cofacets_[dim][k]];
      int face;
      if (UnpairedFaces(cofacet, face) == 1) one_.Insert(cofacet.rank);
    }
  }

  void Clear() {
    for (int d = 0; d < 4; ++d) {
      Pairings& up = gradient_.up[d];
      Pairings& down = gradient_.down[d];
      for (const StarCell& c : star_[d]) {
        if (!up.empty()) up[c.id] = -1;
        if (!down.empty()) down[c.id] = -1;
      }
    }
  }

  void Pair(StarCell& alpha, StarCell& beta) {
    ++pairs_[alpha.dim];
    // An empty array is one the caller does not keep (GradientArrays).
    if (!gradient_.up[alpha.dim].empty()) gradient_.up[alpha.dim][alpha.id] = beta.id;
    if (!gradient_.down[beta.dim].empty()) gradient_.down[beta.dim][beta.id] = alpha.id;
    alpha.paired = true;
    beta.paired = true;
  }

  GradientField& gradient_;
  const Topology& topology_;
  std::array<std::vector<SimplexId>, 4> critical_;
  std::array<int64_t, 3> pairs_{};
  std::array<std::vector<StarCell>, 4> star_;
  std::array<std::vector<int32_t>, 3> cofacet_begin_, cofacets_;  // [1] and [2] used
  std::vector<int32_t> cursor_;
  std::vector<Uint128> ranked_;  // by rank: key and place (RankCells)
  RankSet zero_, one_;
  // BuildFromTetrahedra's scratch: the vertices below x, and the pairs of them in a tetrahedron.
  std::vector<SimplexId> below_;
  std::vector<std::pair<SimplexId, SimplexId>> pairs_below_;
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
// face, ascending, into out[0..d + 1]. Only the vertex not in `ids` is looked for, reading as
// little of the cofacet's encoding as it can: its stored (highest) vertex first, then its edge's
// (a random read each, instead of decoding the whole tuple; pairs point all over the mesh).
void CofacetTokens(const Topology& topology, int d, const SimplexId* ids, SimplexId cofacet,
                   SimplexId* out) {
  const auto in_face = [&](SimplexId internal) {
    const SimplexId input = topology.vertex_input_id(internal);
    return std::find(ids, ids + d + 1, input) != ids + d + 1 ? -1 : input;
  };
  SimplexId extra = -1;
  switch (d) {
    case 0:
      extra = in_face(topology.edge_upper(cofacet));
      if (extra < 0) extra = in_face(topology.edge_lowest(cofacet));
      break;
    case 1: {
      extra = in_face(topology.triangle_third(cofacet));
      if (extra >= 0) break;
      const SimplexId e = topology.triangle_edge(cofacet);
      extra = in_face(topology.edge_upper(e));
      if (extra < 0) extra = in_face(topology.edge_lowest(e));
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

RelationSet DiscreteGradientDeclared() { return {Relation::kVE, Relation::kVF, Relation::kVT}; }

template <class Structure>
absl::StatusOr<DiscreteGradientResult> RunDiscreteGradient(Structure& structure,
                                                           std::span<const SimplexId> order,
                                                           const RunContext& context,
                                                           GradientArrays arrays,
                                                           VertexNeighbors* neighbors) {
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
    if (all || d == 3) unpaired(g.down[d], d);
  }
  // Every cell lies in the lower star of exactly one vertex (its highest), so consumers on
  // different blocks write disjoint entries. Each counts what it pairs and lists what it leaves
  // critical, so no pass over every cell follows. Blocks go out in runs to whichever consumer
  // is free: a block's cost depends on the structure (on actopo, on what its producers had
  // ready), and equal halves left one consumer 0.55 s behind the other (part_5M.vtu).
  const int consumers = std::max(context.consumers, 1);
  std::vector<std::array<std::vector<SimplexId>, 4>> critical(consumers);
  std::vector<std::array<int64_t, 3>> pairs(consumers);
  const absl::Status status = RunOnConsumersShared(
      context, topo.num_blocks(), std::max(1, topo.num_blocks() / (16 * consumers)),
      [&](int consumer, ItemQueue& queue, WorkTracker& tracker) {
        auto reader = structure.NewReader();
        LowerStarPairing pairing(g, topo);
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

template <class Structure>
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
  constexpr bool kFromTetrahedra = !std::is_same_v<Structure, ExplicitStructure>;
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

template absl::StatusOr<DiscreteGradientResult> UpdateDiscreteGradient(
    ExplicitStructure&, DiscreteGradientResult, std::span<const SimplexId>,
    std::span<const SimplexId>, const RunContext&, std::span<const SimplexId>);
template absl::StatusOr<DiscreteGradientResult> UpdateDiscreteGradient(
    CompactStructure&, DiscreteGradientResult, std::span<const SimplexId>,
    std::span<const SimplexId>, const RunContext&, std::span<const SimplexId>);
template absl::StatusOr<DiscreteGradientResult> UpdateDiscreteGradient(
    ActopoStructure&, DiscreteGradientResult, std::span<const SimplexId>,
    std::span<const SimplexId>, const RunContext&, std::span<const SimplexId>);

template absl::StatusOr<DiscreteGradientResult> RunDiscreteGradient(ExplicitStructure&,
                                                                    std::span<const SimplexId>,
                                                                    const RunContext&,
                                                                    GradientArrays,
                                                                    VertexNeighbors*);
template absl::StatusOr<DiscreteGradientResult> RunDiscreteGradient(CompactStructure&,
                                                                    std::span<const SimplexId>,
                                                                    const RunContext&,
                                                                    GradientArrays,
                                                                    VertexNeighbors*);
template absl::StatusOr<DiscreteGradientResult> RunDiscreteGradient(ActopoStructure&,
                                                                    std::span<const SimplexId>,
                                                                    const RunContext&,
                                                                    GradientArrays,
                                                                    VertexNeighbors*);

}  // namespace actopo
