// The static baseline: every declared relation computed for the whole mesh at preprocessing
// (block-parallel) and kept in flat arrays, like TTK's ExplicitTriangulation.
//
//   ASSIGN_OR_RETURN(auto structure, ExplicitStructure::Build(topology, {.relations = declared}));
//   ExplicitStructure::Reader reader = structure->NewReader();
//   for (SimplexId t : reader.vertex_star(v)) ...
//
// Readers are free to copy and to use from any number of threads at once (read-only data).
// Asking a reader for a relation outside the declared set is a programming error and aborts.
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
  struct Options {
    RelationSet relations = RelationSet::All();
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
    std::span<const SimplexId> Lookup(SimplexId s) const {
      const Stored& st = owner_->stored_[Index(R)];
      if (!st.present) [[unlikely]] MissingRelation(R);
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
    const ExplicitStructure* owner_;
  };

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
