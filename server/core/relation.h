// The relations of a 3D simplicial complex and their canonical orders.
//
// Inside the core a relation has a two-letter code (VE = vertex -> edges, FT = triangle ->
// tetrahedra, ...); outside it is spelled out (RelationName(Relation::kVE) == "vertex_edges").
//
//   for (Relation r : AllRelations()) std::cout << RelationName(r) << "\n";
#ifndef ACTOPO_SERVER_CORE_RELATION_H_
#define ACTOPO_SERVER_CORE_RELATION_H_

#include <array>
#include <cstdint>
#include <optional>
#include <span>
#include <string_view>

namespace actopo {

// Order matters: it is the order of the topo-relations sweeps' report and of the wire enum.
enum class Relation : uint8_t {
  kVV,  // vertex -> adjacent vertices, ascending
  kVE,  // vertex -> incident edges, ascending
  kVF,  // vertex -> incident triangles, ascending
  kVT,  // vertex -> incident tetrahedra (star), ascending
  kEV,  // edge -> its 2 vertices, ascending
  kEF,  // edge -> incident triangles, ascending
  kET,  // edge -> incident tetrahedra, ascending
  kFV,  // triangle -> its 3 vertices, ascending
  kFE,  // triangle -> its 3 edges: (v0v1), (v0v2), (v1v2)
  kFT,  // triangle -> incident tetrahedra, ascending
  kTV,  // tetrahedron -> its 4 vertices, ascending
  kTE,  // tetrahedron -> its 6 edges: (v0v1), (v0v2), (v0v3), (v1v2), (v1v3), (v2v3)
  kTF,  // tetrahedron -> its 4 triangles: (v0v1v2), (v0v1v3), (v0v2v3), (v1v2v3)
  kTT,  // tetrahedron -> tetrahedra sharing a triangle, ascending
  kVL,  // vertex link: for each tet of VT(v), in VT order, the triangle opposite v
  kEL,  // edge link: for each tet of ET(e), in ET order, the edge opposite e
  kFL,  // triangle link: for each tet of FT(f), in FT order, the vertex opposite f
  kVB,  // vertex on boundary: one value, 0 or 1
  kEB,  // edge on boundary: one value, 0 or 1
  kFB,  // triangle on boundary (exactly one incident tetrahedron): one value, 0 or 1
  kEE,  // edge -> edges sharing a vertex with it, ascending (itself excluded)
  kFF,  // triangle -> triangles sharing an edge with it, ascending (itself excluded)
};
inline constexpr int kNumRelations = 22;

constexpr int Index(Relation r) { return static_cast<int>(r); }

// Dimension of the simplices a relation is asked of (V=0, E=1, F=2, T=3).
constexpr int SourceDimension(Relation r) {
  constexpr std::array<int8_t, kNumRelations> kDim = {0, 0, 0, 0, 1, 1, 1, 2, 2, 2, 3,
                                                      3, 3, 3, 0, 1, 2, 0, 1, 2, 1, 2};
  return kDim[Index(r)];
}

// Dimension of the simplices in a relation's result; -1 for the boundary predicates.
constexpr int TargetDimension(Relation r) {
  constexpr std::array<int8_t, kNumRelations> kDim = {0, 1, 2, 3, 0, 2, 3,  0,  1,  3, 0,
                                                      1, 2, 3, 2, 1, 0, -1, -1, -1, 1, 2};
  return kDim[Index(r)];
}

// Whether computing or reading R touches edges or triangles, which a topology built without
// faces lacks (TopologyOptions::faces): every relation but VV, VT, TV and VB.
constexpr bool NeedsFaces(Relation r) {
  return r != Relation::kVV && r != Relation::kVT && r != Relation::kTV && r != Relation::kVB;
}

// Number of elements when fixed for every simplex (EV 2, FE 3, ...), 0 when variable.
constexpr int FixedSize(Relation r) {
  constexpr std::array<int8_t, kNumRelations> kSize = {0, 0, 0, 0, 2, 0, 0, 3, 3, 0, 4,
                                                       6, 4, 0, 0, 0, 0, 1, 1, 1, 0, 0};
  return kSize[Index(r)];
}

// EV, FV, TV and FB are read straight from the static encoding; no structure stores them.
constexpr bool IsStatic(Relation r) {
  return r == Relation::kEV || r == Relation::kFV || r == Relation::kTV || r == Relation::kFB;
}

std::string_view RelationName(Relation r);  // "vertex_edges"
std::string_view RelationCode(Relation r);  // "VE"
// Accepts the API name or the two-letter code.
std::optional<Relation> ParseRelation(std::string_view name);
std::span<const Relation> AllRelations();

// A set of relations, e.g. an algorithm's declared set.
class RelationSet {
 public:
  constexpr RelationSet() = default;
  constexpr RelationSet(std::initializer_list<Relation> rs) {
    for (Relation r : rs) Add(r);
  }
  static constexpr RelationSet All() {
    RelationSet s;
    s.bits_ = (1u << kNumRelations) - 1;
    return s;
  }
  constexpr void Add(Relation r) { bits_ |= 1u << Index(r); }
  constexpr void Remove(Relation r) { bits_ &= ~(1u << Index(r)); }
  constexpr bool Contains(Relation r) const { return bits_ & (1u << Index(r)); }
  constexpr bool empty() const { return bits_ == 0; }
  constexpr uint32_t bits() const { return bits_; }
  constexpr bool operator==(const RelationSet&) const = default;
  constexpr RelationSet operator|(const RelationSet& o) const {
    RelationSet s;
    s.bits_ = bits_ | o.bits_;
    return s;
  }

 private:
  uint32_t bits_ = 0;
};

}  // namespace actopo

#endif  // ACTOPO_SERVER_CORE_RELATION_H_
