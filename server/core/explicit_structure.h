// The static baseline: every declared relation computed for the whole mesh at preprocessing
// (block-parallel) and kept in flat arrays, like TTK's ExplicitTriangulation.
//
//   ASSIGN_OR_RETURN(auto structure, ExplicitStructure::Build(topology, {.relations = declared}));
//   ExplicitStructure::Reader reader = structure->NewReader();
//   for (SimplexId t : reader.vertex_star(v)) ...
//
// By default every relation is stored except the edge and triangle neighbours (EE, FF), which
// hold more entries than the others together: a reader composes those rows from the stored
// VE, FE and EF as they are asked for. Declared explicitly, they are stored too.
//
// Readers are free to copy and to use from any number of threads at once (read-only data; each
// reader has its own buffer for composed rows). Asking a reader for a relation that is neither
// stored nor composable from stored ones is a programming error and aborts.
#ifndef ACTOPO_SERVER_CORE_EXPLICIT_STRUCTURE_H_
#define ACTOPO_SERVER_CORE_EXPLICIT_STRUCTURE_H_

#include <array>
#include <memory>
#include <vector>

#include "absl/status/statusor.h"
#include "server/core/progress.h"
#include "server/core/relation.h"
#include "server/core/stats.h"
#include "server/core/structure.h"
#include "server/core/topology.h"

namespace actopo {

class ExplicitStructure {
 public:
  // Everything but EE and FF.
  static constexpr RelationSet DefaultRelations() {
    RelationSet s = RelationSet::All();
    s.Remove(Relation::kEE);
    s.Remove(Relation::kFF);
    return s;
  }

  struct Options {
    RelationSet relations = DefaultRelations();
    int threads = 0;  // preprocessing threads; 0: DefaultThreads()
  };

  // Reports phase "precompute" per relation and stops between relations (CANCELLED or
  // DEADLINE_EXCEEDED, nothing kept) when `progress` says so.
  static absl::StatusOr<std::unique_ptr<ExplicitStructure>> Build(
      std::shared_ptr<const Topology> topology, const Options& options,
      const Progress& progress = {});

  class Reader : public ReaderBase<Reader> {
   public:
    template <Relation R>
    std::span<const SimplexId> Lookup(SimplexId s) {
      const Stored& st = owner_->stored_[Index(R)];
      if constexpr (R == Relation::kEE) {
        if (!st.present) return EdgeNeighbors(s);
      } else if constexpr (R == Relation::kFF) {
        if (!st.present) return TriangleNeighbors(s);
      }
      if (!st.present) [[unlikely]]
        MissingRelation(R);
      if constexpr (FixedSize(R) > 0) {
        return {st.values.data() + size_t(s) * FixedSize(R), size_t(FixedSize(R))};
      } else {
        return {st.values.data() + st.offsets[s], st.values.data() + st.offsets[s + 1]};
      }
    }
    AccessStats stats() const { return {}; }

   private:
    friend class ExplicitStructure;
    explicit Reader(const ExplicitStructure* owner)
        : ReaderBase<Reader>(owner->topology_.get()), owner_(owner) {}
    [[noreturn]] static void MissingRelation(Relation r);
    // Composed rows: VE(a) and VE(b) of edge (a, b); EF of the triangle's three edges; minus
    // the simplex itself, ascending.
    std::span<const SimplexId> EdgeNeighbors(SimplexId e);
    std::span<const SimplexId> TriangleNeighbors(SimplexId f);
    std::span<const SimplexId> Row(Relation r, SimplexId s) const;
    const ExplicitStructure* owner_;
    std::vector<SimplexId> edge_neighbors_, triangle_neighbors_;
  };

  // Traits (structures.h): every relation precomputed, rows read in place; no producers.
  static constexpr bool kRelationsInPlace = true;
  static constexpr bool kPrefetches = false;

  Reader NewReader() const { return Reader(this); }
  const Topology& topology() const { return *topology_; }
  RelationSet relations() const { return relations_; }
  MemoryStats memory() const;

 private:
  struct Stored {
    bool present = false;
    std::vector<SimplexId> offsets;  // empty for fixed-size relations
    std::vector<SimplexId> values;
  };

  explicit ExplicitStructure(std::shared_ptr<const Topology> t) : topology_(std::move(t)) {}

  std::shared_ptr<const Topology> topology_;
  RelationSet relations_;
  std::array<Stored, kNumRelations> stored_;
};

}  // namespace actopo

#endif  // ACTOPO_SERVER_CORE_EXPLICIT_STRUCTURE_H_
