// The interface algorithms are written against: a Reader per consumer thread.
//
// The ACTOPO paper (Liu & Iuricich, "A Task-Parallel Approach for Localized Topological Data
// Structures") and TopoCluster (Liu, Iuricich, Fellegara, De Floriani) compute the relations of a
// block of vertices on demand; ExplicitTriangulation-like structures compute them all up front.
// Here every structure hands out Readers with the same named accessors, so an algorithm is a
// template over the reader type (static dispatch: no virtual call per relation):
//
//   template <class Reader>
//   int64_t CountStars(Reader& reader) {
//     int64_t n = 0;
//     for (SimplexId v = 0; v < reader.topology().num_vertices(); ++v)
//       n += reader.vertex_star(v).size();
//     return n;
//   }
//
// Lifetime rule: a span returned for relation R stays valid until the same reader is next asked
// for relation R. Spans of different relations do not invalidate each other, so nested loops
// over different relations are fine; to keep a row of R while asking R again, copy it.
// tetrahedron_vertices stays valid forever; edge_vertices and triangle_vertices return their
// (decoded) tuples by value.
//
// Ids are internal (see topology.h); translate at the edges with the topology's permutations.
#ifndef ACTOPO_SERVER_CORE_STRUCTURE_H_
#define ACTOPO_SERVER_CORE_STRUCTURE_H_

#include <array>
#include <span>

#include "server/core/block_relations.h"
#include "server/core/mesh.h"
#include "server/core/relation.h"
#include "server/core/topology.h"

namespace actopo {

// Where a caching reader's last span of one relation points: copies of the RelationBlock's
// fields, so a read inside the same block touches one cache line and takes one comparison.
struct RelationSlot {
  SimplexId first = 0;
  SimplexId count = 0;
  const SimplexId* offsets = nullptr;
  const SimplexId* values = nullptr;

  bool Contains(SimplexId s) const {
    return static_cast<uint32_t>(s - first) < static_cast<uint32_t>(count);
  }
  void Point(const RelationBlock& block) {
    first = block.first;
    count = block.count;
    offsets = block.offsets.data();
    values = block.values.data();
  }
  template <Relation R>
  std::span<const SimplexId> Row(SimplexId s) const {
    const size_t i = size_t(s - first);
    if constexpr (FixedSize(R) > 0) {
      return {values + i * FixedSize(R), size_t(FixedSize(R))};
    } else {
      return {values + offsets[i], values + offsets[i + 1]};
    }
  }
};

// CRTP base: Derived provides `template <Relation R> std::span<const SimplexId> Lookup(SimplexId)`
// for the non-static relations.
template <class Derived>
class ReaderBase {
 public:
  const Topology& topology() const { return *topology_; }

  template <Relation R>
  std::span<const SimplexId> get(SimplexId s) {
    if constexpr (R == Relation::kEV) {
      edge_row_ = topology_->edge(s);
      return edge_row_;
    } else if constexpr (R == Relation::kFV) {
      triangle_row_ = topology_->triangle(s);
      return triangle_row_;
    } else if constexpr (R == Relation::kTV) {
      tetrahedron_row_ = topology_->tetrahedron(s);
      return tetrahedron_row_;
    } else if constexpr (R == Relation::kFB) {
      return {&kFlags[topology_->triangle_on_boundary(s) ? 1 : 0], 1};
    } else {
      return static_cast<Derived*>(this)->template Lookup<R>(s);
    }
  }
  // Run-time relation (the service path); algorithms use the named accessors.
  std::span<const SimplexId> get(Relation r, SimplexId s);

  std::span<const SimplexId> vertex_neighbors(SimplexId v) { return get<Relation::kVV>(v); }
  std::span<const SimplexId> vertex_edges(SimplexId v) { return get<Relation::kVE>(v); }
  std::span<const SimplexId> vertex_triangles(SimplexId v) { return get<Relation::kVF>(v); }
  std::span<const SimplexId> vertex_star(SimplexId v) { return get<Relation::kVT>(v); }
  std::span<const SimplexId> vertex_link(SimplexId v) { return get<Relation::kVL>(v); }
  bool vertex_on_boundary(SimplexId v) { return get<Relation::kVB>(v)[0] != 0; }

  std::array<SimplexId, 2> edge_vertices(SimplexId e) const { return topology_->edge(e); }
  std::span<const SimplexId> edge_triangles(SimplexId e) { return get<Relation::kEF>(e); }
  std::span<const SimplexId> edge_star(SimplexId e) { return get<Relation::kET>(e); }
  std::span<const SimplexId> edge_link(SimplexId e) { return get<Relation::kEL>(e); }
  bool edge_on_boundary(SimplexId e) { return get<Relation::kEB>(e)[0] != 0; }
  std::span<const SimplexId> edge_neighbors(SimplexId e) { return get<Relation::kEE>(e); }

  std::array<SimplexId, 3> triangle_vertices(SimplexId f) const { return topology_->triangle(f); }
  std::span<const SimplexId> triangle_edges(SimplexId f) { return get<Relation::kFE>(f); }
  std::span<const SimplexId> triangle_star(SimplexId f) { return get<Relation::kFT>(f); }
  std::span<const SimplexId> triangle_link(SimplexId f) { return get<Relation::kFL>(f); }
  bool triangle_on_boundary(SimplexId f) const { return topology_->triangle_on_boundary(f); }
  std::span<const SimplexId> triangle_neighbors(SimplexId f) { return get<Relation::kFF>(f); }

  std::array<SimplexId, 4> tetrahedron_vertices(SimplexId t) const {
    return topology_->tetrahedron(t);
  }

  // The algorithm is done with block b's relations on this reader (a sweep in block order has
  // passed it). A structure that buffers blocks frees them now rather than when its buffer fills,
  // so a sweep holds the blocks ahead of it, not the capacity's worth behind it. A hint: reading
  // them again afterwards is correct, they are computed again. Explicit keeps everything (this
  // default does nothing); compact and actopo hide it with their own.
  void Finished(int32_t /*block*/) {}
  std::span<const SimplexId> tetrahedron_edges(SimplexId t) { return get<Relation::kTE>(t); }
  std::span<const SimplexId> tetrahedron_triangles(SimplexId t) { return get<Relation::kTF>(t); }
  std::span<const SimplexId> tetrahedron_neighbors(SimplexId t) { return get<Relation::kTT>(t); }

 protected:
  explicit ReaderBase(const Topology* topology) : topology_(topology) {}
  const Topology* topology_;

 private:
  static constexpr SimplexId kFlags[2] = {0, 1};
  // Where get<EV>, get<FV> and get<TV> decode their rows.
  std::array<SimplexId, 2> edge_row_{};
  std::array<SimplexId, 3> triangle_row_{};
  std::array<SimplexId, 4> tetrahedron_row_{};
};

// A reader whose relations come in blocks (compact, actopo): per relation a slot on the block its
// last row came from. A row inside that block is read in place; one outside moves the slot
// (Derived::MoveSlot(Relation, int32_t block), which points it at that block's relation).
template <class Derived, class Slot>
class BlockSlotReader : public ReaderBase<Derived> {
 public:
  template <Relation R>
  std::span<const SimplexId> Lookup(SimplexId s) {
    Slot& slot = slots_[Index(R)];
    if (!slot.Contains(s)) [[unlikely]] {
      static_cast<Derived*>(this)->MoveSlot(R, this->topology_->block_of(SourceDimension(R), s));
    }
    return slot.template Row<R>(s);
  }

 protected:
  BlockSlotReader(const Topology* topology, const std::array<Slot, kNumRelations>& slots)
      : ReaderBase<Derived>(topology), slots_(slots) {}
  std::array<Slot, kNumRelations> slots_;
};

template <class Derived>
std::span<const SimplexId> ReaderBase<Derived>::get(Relation r, SimplexId s) {
  switch (r) {
    case Relation::kVV: return get<Relation::kVV>(s);
    case Relation::kVE: return get<Relation::kVE>(s);
    case Relation::kVF: return get<Relation::kVF>(s);
    case Relation::kVT: return get<Relation::kVT>(s);
    case Relation::kEV: return get<Relation::kEV>(s);
    case Relation::kEF: return get<Relation::kEF>(s);
    case Relation::kET: return get<Relation::kET>(s);
    case Relation::kFV: return get<Relation::kFV>(s);
    case Relation::kFE: return get<Relation::kFE>(s);
    case Relation::kFT: return get<Relation::kFT>(s);
    case Relation::kTV: return get<Relation::kTV>(s);
    case Relation::kTE: return get<Relation::kTE>(s);
    case Relation::kTF: return get<Relation::kTF>(s);
    case Relation::kTT: return get<Relation::kTT>(s);
    case Relation::kVL: return get<Relation::kVL>(s);
    case Relation::kEL: return get<Relation::kEL>(s);
    case Relation::kFL: return get<Relation::kFL>(s);
    case Relation::kVB: return get<Relation::kVB>(s);
    case Relation::kEB: return get<Relation::kEB>(s);
    case Relation::kFB: return get<Relation::kFB>(s);
    case Relation::kEE: return get<Relation::kEE>(s);
    case Relation::kFF: return get<Relation::kFF>(s);
  }
  return {};
}

}  // namespace actopo

#endif  // ACTOPO_SERVER_CORE_STRUCTURE_H_
