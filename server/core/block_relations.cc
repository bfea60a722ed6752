#include "server/core/block_relations.h"

#include <algorithm>
#include <array>
#include <bit>
#include <cassert>
#include <functional>
#include <memory>

namespace actopo {
namespace {

// Local vertex orders of the faces of a sorted tuple, as relation.h fixes them.
constexpr int kTetEdges[6][2] = {{0, 1}, {0, 2}, {0, 3}, {1, 2}, {1, 3}, {2, 3}};
constexpr int kTetFaces[4][3] = {{0, 1, 2}, {0, 1, 3}, {0, 2, 3}, {1, 2, 3}};
// The vertex of a tetrahedron opposite each face of kTetFaces, and the edge opposite each edge.
constexpr int kOppositeVertex[4] = {3, 2, 1, 0};

class BlockComputer {
 public:
  BlockComputer(const Topology& topology, int32_t b, BlockScratch& scratch)
      : topo_(topology), b_(b), s_(scratch) {
    vbegin_ = topo_.block_vertex_begin(b);
    vend_ = topo_.block_vertex_begin(b + 1);
  }

  RelationBlock Compute(Relation r) {
    RelationBlock out;
    out.relation = r;
    out.block = b_;
    const int dim = SourceDimension(r);
    out.first = topo_.block_begin(dim, b_);
    out.count = topo_.block_size(dim, b_);
    switch (r) {
      case Relation::kVV: VertexNeighbors(out); break;
      case Relation::kVE: VertexEdges(out); break;
      case Relation::kVF: VertexTriangles(out); break;
      case Relation::kVT: VertexStar(out); break;
      case Relation::kEF: EdgeTriangles(out); break;
      case Relation::kET: EdgeStar(out); break;
      case Relation::kFE: TriangleEdges(out); break;
      case Relation::kFT: TriangleStar(out); break;
      case Relation::kTE: TetrahedronEdges(out); break;
      case Relation::kTF: TetrahedronTriangles(out); break;
      case Relation::kTT: TetrahedronNeighbors(out); break;
      case Relation::kVL: VertexLink(out); break;
      case Relation::kEL: EdgeLink(out); break;
      case Relation::kFL: TriangleLink(out); break;
      case Relation::kVB: VertexOnBoundary(out); break;
      case Relation::kEB: EdgeOnBoundary(out); break;
      case Relation::kEE: EdgeNeighbors(out); break;
      case Relation::kFF: TriangleNeighbors(out); break;
      case Relation::kEV:
      case Relation::kFV:
      case Relation::kTV:
      case Relation::kFB: assert(false && "static relations are read from the topology"); break;
    }
    return out;
  }

 private:
  bool Inside(SimplexId v) const { return v >= vbegin_ && v < vend_; }

  // Visits the external then the internal tetrahedra of a block: ascending ids.
  template <class Fn>
  void ForEachTet(int32_t block, Fn&& fn) const {
    for (SimplexId t : topo_.external_tetrahedra(block)) fn(t, topo_.tetrahedron(t).data());
    const SimplexId end = topo_.block_tetrahedron_begin(block + 1);
    for (SimplexId t = topo_.block_tetrahedron_begin(block); t < end; ++t) {
      fn(t, topo_.tetrahedron(t).data());
    }
  }

  // For each of `n` ascending targets, known to be in the run of `ids` from `first` (ascending
  // from base a), its index, in one pass.
  static void FindInRun(const NarrowIds& ids, SimplexId first, SimplexId a,
                        const SimplexId* targets, int n, SimplexId* out) {
    for (int i = 0; i < n; ++i) out[i] = first = ids.Seek(first, a, targets[i]);
  }
  // Edge (a, w) for each of `n` ascending upper vertices w of a.
  void EdgesFrom(SimplexId a, const SimplexId* w, int n, SimplexId* out) const {
    FindInRun(topo_.edge_uppers(), topo_.vertex_first_edge(a), a, w, n, out);
  }
  // Triangle (a, b, c) for each of `n` ascending third vertices c of edge e = (a, b).
  void TrianglesOn(SimplexId a, SimplexId e, const SimplexId* c, int n, SimplexId* out) const {
    FindInRun(topo_.triangle_thirds(), topo_.edge_first_triangle(e), a, c, n, out);
  }
  // The 6 edges of sorted tetrahedron s in kTetEdges order: three runs read once each.
  void TetEdges(const SimplexId* s, SimplexId* out) const {
    EdgesFrom(s[0], s + 1, 3, out);
    EdgesFrom(s[1], s + 2, 2, out + 3);
    EdgesFrom(s[2], s + 3, 1, out + 5);
  }
  // The 4 triangles of sorted tetrahedron s in kTetFaces order.
  void TetFaces(const SimplexId* s, SimplexId* out) const {
    SimplexId e[3];  // (s0, s1), (s0, s2), then (s1, s2)
    EdgesFrom(s[0], s + 1, 2, e);
    EdgesFrom(s[1], s + 2, 1, e + 2);
    TrianglesOn(s[0], e[0], s + 2, 2, out);  // (s0 s1 s2), (s0 s1 s3)
    TrianglesOn(s[0], e[1], s + 3, 1, out + 2);
    TrianglesOn(s[1], e[2], s + 3, 1, out + 3);
  }

  SimplexId Face(const SimplexId* s, int f) const {
    return topo_.FindTriangle(s[kTetFaces[f][0]], s[kTetFaces[f][1]], s[kTetFaces[f][2]]);
  }
  SimplexId Edge(const SimplexId* s, int e) const {
    return topo_.FindEdge(s[kTetEdges[e][0]], s[kTetEdges[e][1]]);
  }

  void BeginPairs() {
    s_.rows.clear();
    s_.values.clear();
  }
  void Pair(SimplexId row, SimplexId value) {
    s_.rows.push_back(row);
    s_.values.push_back(value);
  }
  // Turns the (row, value) pairs into CSR, stable per row; `dedupe` sorts each row and drops
  // repeats (for relations gathered from several tetrahedra).
  void PairsToCsr(RelationBlock& out, bool dedupe) {
    const SimplexId n = out.count;
    out.offsets.assign(size_t(n) + 1, 0);
    for (SimplexId r : s_.rows) ++out.offsets[r + 1];
    for (SimplexId i = 0; i < n; ++i) out.offsets[i + 1] += out.offsets[i];
    s_.tmp.resize(s_.values.size());
    s_.counts.assign(out.offsets.begin(), out.offsets.end() - 1);
    for (size_t k = 0; k < s_.rows.size(); ++k) s_.tmp[s_.counts[s_.rows[k]]++] = s_.values[k];
    if (!dedupe) {
      out.values.assign(s_.tmp.begin(), s_.tmp.end());
      return;
    }
    SimplexId write = 0;
    for (SimplexId i = 0; i < n; ++i) {
      SimplexId* begin = s_.tmp.data() + out.offsets[i];
      SimplexId* end = s_.tmp.data() + out.offsets[i + 1];
      std::sort(begin, end);
      end = std::unique(begin, end);
      out.offsets[i] = write;
      for (SimplexId* p = begin; p != end; ++p) s_.tmp[write++] = *p;
    }
    out.offsets[n] = write;
    out.values.assign(s_.tmp.begin(), s_.tmp.begin() + write);
  }

  void VertexStar(RelationBlock& out) {
    BeginPairs();
    ForEachTet(b_, [&](SimplexId t, const SimplexId* s) {
      for (int k = 0; k < 4; ++k) {
        if (Inside(s[k])) Pair(s[k] - vbegin_, t);
      }
    });
    PairsToCsr(out, false);
  }

  // Vertex relations split each row in two. Simplices whose lowest vertex is v are a contiguous
  // id range starting at v (edges (v, w), triangles (v, a, b)), sorted, with ids above those of
  // every simplex that has a lower vertex. Only the "lower" part, where v is not the lowest
  // vertex, is gathered from the tetrahedra; rows are then lower part + upper range.
  template <class Upper>
  void AppendUpperRanges(RelationBlock& out, Upper&& upper) {
    // out holds the lower parts as CSR; rebuild in s_.values with the upper ranges appended.
    s_.values.clear();
    SimplexId begin = 0;
    for (SimplexId i = 0; i < out.count; ++i) {
      const SimplexId end = out.offsets[i + 1];
      s_.values.insert(s_.values.end(), out.values.begin() + begin, out.values.begin() + end);
      begin = end;
      upper(vbegin_ + i, s_.values);
      out.offsets[i + 1] = static_cast<SimplexId>(s_.values.size());
    }
    out.values.assign(s_.values.begin(), s_.values.end());
  }

  // The vertices that can be the lowest vertex of an edge or triangle holding an inside vertex,
  // ascending: the outside vertices below the block that external tetrahedra reach, then the
  // inside vertices. Walking their edge and triangle runs visits each such face once, in id
  // order, with no search (edges (a, *) and triangles (a, b, *) are runs).
  template <class Fn>
  void ForEachLowestCandidate(Fn&& fn) {
    // Each such vertex is in several external tetrahedra: made unique through a table first,
    // then sorted, so that the sort does not pay for every occurrence.
    const auto external = topo_.external_tetrahedra(b_);
    LinkVertexIndex& unique = s_.link_vertices;
    unique.Reset(external.size());
    for (SimplexId t : external) {
      for (SimplexId v : topo_.tetrahedron(t)) {
        if (v < vbegin_) unique.IndexOf(v);
      }
    }
    s_.candidates.assign(unique.vertices().begin(), unique.vertices().end());
    std::sort(s_.candidates.begin(), s_.candidates.end());
    for (SimplexId a : s_.candidates) fn(a);
    for (SimplexId a = vbegin_; a < vend_; ++a) fn(a);
  }

  // The lower parts of the vertex rows (edges (a, v) with a < v), as CSR: value(a, e) per edge.
  template <class Value>
  void LowerEdges(RelationBlock& out, Value&& value) {
    BeginPairs();
    ForEachLowestCandidate([&](SimplexId a) {
      for (SimplexId e = topo_.vertex_first_edge(a); e < topo_.vertex_first_edge(a + 1); ++e) {
        const SimplexId b = topo_.edge_upper(e, a);
        if (Inside(b)) Pair(b - vbegin_, value(a, e));
      }
    });
    PairsToCsr(out, false);
  }

  // VV and VB need no faces (TopologyOptions::faces), so that critical points can run without
  // them: VV comes from the vertices' stars, VB from the block's tetrahedra.

  // The block's vertex stars as CSR (VT), for VV.
  RelationBlock BlockStars(const RelationBlock& out) {
    RelationBlock star;
    star.count = out.count;
    VertexStar(star);
    return star;
  }
  // The other vertices of v's star tetrahedra (the other ends of v's edges), numbered in the
  // order first met, in s_.link_vertices.
  void IndexLinkVertices(SimplexId v, std::span<const SimplexId> star) {
    LinkVertexIndex& index = s_.link_vertices;
    index.Reset(star.size());
    for (SimplexId t : star) {
      for (SimplexId w : topo_.tetrahedron(t)) {
        if (w != v) index.IndexOf(w);
      }
    }
  }
  void VertexNeighbors(RelationBlock& out) {
    const RelationBlock star = BlockStars(out);
    out.offsets.assign(size_t(out.count) + 1, 0);
    out.values.clear();
    for (SimplexId i = 0; i < out.count; ++i) {
      IndexLinkVertices(vbegin_ + i, star.row(i));
      const auto row = s_.link_vertices.vertices();
      out.values.insert(out.values.end(), row.begin(), row.end());
      std::sort(out.values.begin() + out.offsets[i], out.values.end());
      out.offsets[i + 1] = SimplexId(out.values.size());
    }
  }

  void VertexEdges(RelationBlock& out) {
    LowerEdges(out, [](SimplexId, SimplexId e) { return e; });
    AppendUpperRanges(out, [&](SimplexId v, std::vector<SimplexId>& row) {
      for (SimplexId e = topo_.vertex_first_edge(v); e < topo_.vertex_first_edge(v + 1); ++e) {
        row.push_back(e);
      }
    });
  }

  void VertexTriangles(RelationBlock& out) {
    // Lower parts: triangles (a, b, c) with b or c inside, from the runs of every candidate a.
    BeginPairs();
    ForEachLowestCandidate([&](SimplexId a) {
      for (SimplexId e = topo_.vertex_first_edge(a); e < topo_.vertex_first_edge(a + 1); ++e) {
        const SimplexId b = topo_.edge_upper(e, a);
        const bool b_inside = Inside(b);
        for (SimplexId f = topo_.edge_first_triangle(e); f < topo_.edge_first_triangle(e + 1);
             ++f) {
          const SimplexId c = topo_.triangle_third(f, a);
          if (b_inside) Pair(b - vbegin_, f);
          if (Inside(c)) Pair(c - vbegin_, f);
        }
      }
    });
    PairsToCsr(out, false);
    AppendUpperRanges(out, [&](SimplexId v, std::vector<SimplexId>& row) {
      for (SimplexId f = topo_.vertex_first_triangle(v); f < topo_.vertex_first_triangle(v + 1);
           ++f) {
        row.push_back(f);
      }
    });
  }

  void EdgeStar(RelationBlock& out) {
    BeginPairs();
    ForEachTet(b_, [&](SimplexId t, const SimplexId* s) {
      for (int e = 0; e < 6; ++e) {
        if (Inside(s[kTetEdges[e][0]])) Pair(Edge(s, e) - out.first, t);
      }
    });
    PairsToCsr(out, false);
  }

  void EdgeTriangles(RelationBlock& out) {
    // As for vertices: the triangles (a, b, c) with c > b of edge (a, b) are a contiguous, sorted
    // run at the end of the row; only the others, (c, a, b) and (a, c, b), are looked up.
    BeginPairs();
    ForEachTet(b_, [&](SimplexId, const SimplexId* s) {
      SimplexId face_id[4] = {-1, -1, -1, -1};  // looked up once per tetrahedron
      for (int e = 0; e < 6; ++e) {
        const int i = kTetEdges[e][0], j = kTetEdges[e][1];
        if (!Inside(s[i])) continue;
        SimplexId edge = -1;
        for (int k = 0; k < j; ++k) {  // k > j: the upper run, added below
          if (k == i) continue;
          if (edge < 0) edge = Edge(s, e) - out.first;
          const int f = 3 - (6 - i - j - k);  // face f of kTetFaces omits vertex 3 - f
          if (face_id[f] < 0) face_id[f] = Face(s, f);
          Pair(edge, face_id[f]);
        }
      }
    });
    PairsToCsr(out, true);
    s_.values.clear();
    SimplexId begin = 0;
    for (SimplexId i = 0; i < out.count; ++i) {
      const SimplexId end = out.offsets[i + 1];
      s_.values.insert(s_.values.end(), out.values.begin() + begin, out.values.begin() + end);
      begin = end;
      const SimplexId e = out.first + i;
      for (SimplexId f = topo_.edge_first_triangle(e); f < topo_.edge_first_triangle(e + 1); ++f) {
        s_.values.push_back(f);
      }
      out.offsets[i + 1] = static_cast<SimplexId>(s_.values.size());
    }
    out.values.assign(s_.values.begin(), s_.values.end());
  }

  // Rows of relation `r` of any simplex, computed block by block as asked (this block's first).
  // For the neighbour relations, whose rows join rows of simplices other blocks may own.
  class RowsOf {
   public:
    RowsOf(const Topology& topology, Relation r) : topo_(topology), r_(r) {}
    std::span<const SimplexId> row(SimplexId s) {
      const int32_t block = topo_.block_of(SourceDimension(r_), s);
      auto it = std::find_if(blocks_.begin(), blocks_.end(),
                             [&](const auto& b) { return b->block == block; });
      if (it == blocks_.end()) {
        blocks_.push_back(
            std::make_unique<RelationBlock>(BlockComputer(topo_, block, scratch_).Compute(r_)));
        it = blocks_.end() - 1;
      }
      return (*it)->row(s - (*it)->first);
    }

   private:
    const Topology& topo_;
    const Relation r_;
    BlockScratch scratch_;
    std::vector<std::unique_ptr<RelationBlock>> blocks_;  // a handful: this block and neighbours
  };

  // `out` row by row: the sorted union of `rows` minus the simplex itself.
  void UnionRows(RelationBlock& out,
                 const std::function<void(SimplexId, std::vector<SimplexId>&)>& rows) {
    out.offsets.assign(size_t(out.count) + 1, 0);
    out.values.clear();
    for (SimplexId i = 0; i < out.count; ++i) {
      const SimplexId self = out.first + i;
      s_.tmp.clear();
      rows(self, s_.tmp);
      std::sort(s_.tmp.begin(), s_.tmp.end());
      s_.tmp.erase(std::unique(s_.tmp.begin(), s_.tmp.end()), s_.tmp.end());
      for (SimplexId x : s_.tmp) {
        if (x != self) out.values.push_back(x);
      }
      out.offsets[i + 1] = static_cast<SimplexId>(out.values.size());
    }
  }

  // EE: the edges at either end of the edge. Its lower end is in this block, its upper end may
  // be in another, whose VE is computed too (once per block).
  void EdgeNeighbors(RelationBlock& out) {
    RowsOf ve(topo_, Relation::kVE);
    UnionRows(out, [&](SimplexId e, std::vector<SimplexId>& row) {
      for (SimplexId v : topo_.edge(e)) {
        const auto around = ve.row(v);
        row.insert(row.end(), around.begin(), around.end());
      }
    });
  }

  // FF: the triangles on the triangle's three edges. Edges (a, b) and (a, c) belong to this
  // block, (b, c) may belong to another, whose EF is computed too (once per block).
  void TriangleNeighbors(RelationBlock& out) {
    RowsOf ef(topo_, Relation::kEF);
    UnionRows(out, [&](SimplexId f, std::vector<SimplexId>& row) {
      const auto [a, b, c] = topo_.triangle(f);
      for (SimplexId e : {topo_.FindEdge(a, b), topo_.FindEdge(a, c), topo_.FindEdge(b, c)}) {
        const auto around = ef.row(e);
        row.insert(row.end(), around.begin(), around.end());
      }
    });
  }

  void TriangleEdges(RelationBlock& out) {
    out.stride = 3;
    out.values.resize(size_t(out.count) * 3);
    // The block's triangles (a, b, c) in id order: by a, then by edge (a, b), then by c.
    for (SimplexId a = vbegin_; a < vend_; ++a) {
      for (SimplexId e = topo_.vertex_first_edge(a); e < topo_.vertex_first_edge(a + 1); ++e) {
        const SimplexId b = topo_.edge_upper(e, a);
        for (SimplexId f = topo_.edge_first_triangle(e); f < topo_.edge_first_triangle(e + 1);
             ++f) {
          const SimplexId c = topo_.triangle_third(f, a);
          SimplexId* row = &out.values[3 * size_t(f - out.first)];
          row[0] = e;
          row[1] = topo_.FindEdge(a, c);
          row[2] = topo_.FindEdge(b, c);
        }
      }
    }
  }

  // Pairs (local triangle, tetrahedron) for the triangles owned by the block, ascending tets.
  void TriangleStarPairs(SimplexId first) {
    BeginPairs();
    ForEachTet(b_, [&](SimplexId t, const SimplexId* s) {
      if (!Inside(s[0]) && !Inside(s[1])) return;  // no face has its lowest vertex inside
      SimplexId faces[4];
      TetFaces(s, faces);
      for (int f = 0; f < 4; ++f) {
        if (Inside(s[kTetFaces[f][0]])) Pair(faces[f] - first, t);
      }
    });
  }

  void TriangleStar(RelationBlock& out) {
    TriangleStarPairs(out.first);
    PairsToCsr(out, false);
  }

  void TetrahedronEdges(RelationBlock& out) {
    out.stride = 6;
    out.values.resize(size_t(out.count) * 6);
    for (SimplexId i = 0; i < out.count; ++i) {
      TetEdges(topo_.tetrahedron(out.first + i).data(), &out.values[6 * size_t(i)]);
    }
  }

  void TetrahedronTriangles(RelationBlock& out) {
    out.stride = 4;
    out.values.resize(size_t(out.count) * 4);
    for (SimplexId i = 0; i < out.count; ++i) {
      TetFaces(topo_.tetrahedron(out.first + i).data(), &out.values[4 * size_t(i)]);
    }
  }

  void TetrahedronNeighbors(RelationBlock& out) {
    // Triangles owned by this block: their stars come from the block's own tetrahedra.
    RelationBlock star;
    star.first = topo_.block_triangle_begin(b_);
    star.count = topo_.block_size(2, b_);
    TriangleStarPairs(star.first);
    PairsToCsr(star, false);

    // The triangle opposite a tetrahedron's lowest vertex may belong to a later block; collect
    // those as (owner block, triangle, local tet) requests, answered from the owner's tets below.
    std::vector<int64_t>& foreign = s_.keys;
    foreign.clear();
    BeginPairs();
    for (SimplexId i = 0; i < out.count; ++i) {
      const SimplexId t = out.first + i;
      SimplexId faces[4];
      TetFaces(topo_.tetrahedron(t).data(), faces);
      for (SimplexId id : faces) {
        if (id >= star.first && id < star.first + star.count) {
          for (SimplexId other : star.row(id - star.first)) {
            if (other != t) Pair(i, other);
          }
        } else {
          foreign.push_back(int64_t(id) << 32 | i);
        }
      }
    }
    std::sort(foreign.begin(), foreign.end());
    for (size_t group = 0; group < foreign.size();) {
      const int32_t owner = topo_.block_of(2, SimplexId(foreign[group] >> 32));
      size_t end = group;
      while (end < foreign.size() && topo_.block_of(2, SimplexId(foreign[end] >> 32)) == owner) {
        ++end;
      }
      AnswerForeignStars(owner, foreign.data() + group, foreign.data() + end, out.first);
      group = end;
    }
    PairsToCsr(out, true);
  }

  // requests: sorted (triangle << 32 | local tet) whose triangles all belong to block `owner`.
  void AnswerForeignStars(int32_t owner, const int64_t* begin, const int64_t* end,
                          SimplexId first_tet) {
    const SimplexId obegin = topo_.block_vertex_begin(owner);
    const SimplexId oend = topo_.block_vertex_begin(owner + 1);
    s_.mark.assign(size_t(oend - obegin), 0);
    for (const int64_t* r = begin; r != end; ++r) {
      s_.mark[topo_.edge_lowest(topo_.triangle_edge(SimplexId(*r >> 32))) - obegin] = 1;
    }
    ForEachTet(owner, [&](SimplexId t, const SimplexId* s) {
      for (int f = 0; f < 4; ++f) {
        const SimplexId low = s[kTetFaces[f][0]];
        if (low < obegin || low >= oend || !s_.mark[low - obegin]) continue;
        const int64_t key = int64_t(Face(s, f)) << 32;
        for (const int64_t* r = std::lower_bound(begin, end, key);
             r != end && (*r >> 32) == (key >> 32); ++r) {
          const SimplexId local = SimplexId(*r & 0xffffffff);
          if (first_tet + local != t) Pair(local, t);
        }
      }
    });
  }

  void VertexLink(RelationBlock& out) {
    VertexStar(out);
    for (SimplexId i = 0; i < out.count; ++i) {
      const SimplexId v = vbegin_ + i;
      for (SimplexId k = out.offsets[i]; k < out.offsets[i + 1]; ++k) {
        const auto s = topo_.tetrahedron(out.values[k]);
        const int at = int(std::find(s.begin(), s.end(), v) - s.begin());
        out.values[k] =
            Face(s.data(), kOppositeVertex[at]);  // face f omits vertex kOppositeVertex[f]
      }
    }
  }

  void EdgeLink(RelationBlock& out) {
    EdgeStar(out);
    for (SimplexId i = 0; i < out.count; ++i) {
      const auto edge = topo_.edge(out.first + i);
      for (SimplexId k = out.offsets[i]; k < out.offsets[i + 1]; ++k) {
        const auto s = topo_.tetrahedron(out.values[k]);
        SimplexId other[2];
        int n = 0;
        for (int j = 0; j < 4; ++j) {
          if (s[j] != edge[0] && s[j] != edge[1]) other[n++] = s[j];
        }
        out.values[k] = topo_.FindEdge(other[0], other[1]);
      }
    }
  }

  void TriangleLink(RelationBlock& out) {
    TriangleStar(out);
    for (SimplexId i = 0; i < out.count; ++i) {
      const auto f = topo_.triangle(out.first + i);
      for (SimplexId k = out.offsets[i]; k < out.offsets[i + 1]; ++k) {
        const auto s = topo_.tetrahedron(out.values[k]);
        for (int j = 0; j < 4; ++j) {
          if (s[j] != f[0] && s[j] != f[1] && s[j] != f[2]) out.values[k] = s[j];
        }
      }
    }
  }

  // Calls fn(a, e, f) for every triangle f = (a, b, c) whose lowest vertex a is a candidate
  // (ForEachLowestCandidate), e = (a, b) its edge: every triangle holding an inside vertex.
  template <class Fn>
  void ForEachCandidateTriangle(Fn&& fn) {
    ForEachLowestCandidate([&](SimplexId a) {
      for (SimplexId e = topo_.vertex_first_edge(a); e < topo_.vertex_first_edge(a + 1); ++e) {
        for (SimplexId f = topo_.edge_first_triangle(e); f < topo_.edge_first_triangle(e + 1);
             ++f) {
          fn(a, e, f);
        }
      }
    });
  }

  // A vertex or edge is on the boundary iff it is a face of a boundary triangle, one that lies
  // in one tetrahedron only.
  // A vertex: the block's triangles with a vertex inside are counted over its tetrahedra. Every
  // tetrahedron with such a triangle has that vertex, so is the block's: each tetrahedron is read
  // once (scanning each vertex's star would read it once per vertex it has inside, mostly four
  // times) and no faces are needed (TopologyOptions::faces).
  void VertexOnBoundary(RelationBlock& out) {
    out.stride = 1;
    out.values.assign(out.count, 0);
    const size_t tets =
        topo_.external_tetrahedra(b_).size() +
        size_t(topo_.block_tetrahedron_begin(b_ + 1) - topo_.block_tetrahedron_begin(b_));
    // About two distinct triangles per tetrahedron (each inner one is shared by two): the table
    // stays at most half full.
    const size_t capacity = std::bit_ceil(std::max<size_t>(16, 4 * tets));
    const size_t mask = capacity - 1;
    std::vector<TriangleCount>& table = s_.triangles;
    table.assign(capacity, TriangleCount{});
    ForEachTet(b_, [&](SimplexId, const SimplexId* s) {
      for (const auto& face : kTetFaces) {
        const SimplexId a = s[face[0]], b = s[face[1]], c = s[face[2]];
        if (!Inside(a) && !Inside(b) && !Inside(c)) continue;
        size_t slot = ((uint64_t(uint32_t(a)) * 0x9E3779B97F4A7C15ULL ^
                        uint64_t(uint32_t(b)) * 0xC2B2AE3D27D4EB4FULL ^
                        uint64_t(uint32_t(c)) * 0x165667B19E3779F9ULL) >>
                       32) &
                      mask;
        for (;; slot = (slot + 1) & mask) {
          TriangleCount& entry = table[slot];
          if (entry.a < 0) {
            entry = {a, b, c, 1};
            break;
          }
          if (entry.a == a && entry.b == b && entry.c == c) {
            entry.count = 2;  // two or more: not on the boundary
            break;
          }
        }
      }
    });
    for (const TriangleCount& entry : table) {
      if (entry.count != 1) continue;
      for (SimplexId v : {entry.a, entry.b, entry.c}) {
        if (Inside(v)) out.values[v - vbegin_] = 1;
      }
    }
  }

  // An edge: from the boundary bits of the triangles the block's vertices can be in.
  void EdgeOnBoundary(RelationBlock& out) {
    out.stride = 1;
    out.values.assign(out.count, 0);
    // Boundary triangles are few: their other two edges are searched for.
    ForEachCandidateTriangle([&](SimplexId a, SimplexId e, SimplexId f) {
      if (!topo_.triangle_on_boundary(f)) return;
      const SimplexId b = topo_.edge_upper(e, a), c = topo_.triangle_third(f, a);
      if (Inside(a)) {
        out.values[e - out.first] = 1;
        out.values[topo_.FindEdge(a, c) - out.first] = 1;
      }
      if (Inside(b)) out.values[topo_.FindEdge(b, c) - out.first] = 1;
    });
  }

  const Topology& topo_;
  const int32_t b_;
  BlockScratch& s_;
  SimplexId vbegin_ = 0, vend_ = 0;
};

}  // namespace

RelationBlock ComputeBlockRelation(const Topology& topology, Relation r, int32_t b,
                                   BlockScratch& scratch) {
  return BlockComputer(topology, b, scratch).Compute(r);
}

}  // namespace actopo
