#include "server/core/explicit_structure.h"

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <iterator>

#include "absl/strings/str_cat.h"
#include "server/core/block_relations.h"
#include "server/core/parallel.h"
#include "server/core/status_macros.h"

namespace actopo {

void ExplicitStructure::Reader::MissingRelation(Relation r) {
  std::fprintf(stderr,
               "actopo: relation %s was not declared when the explicit structure was built\n",
               std::string(RelationName(r)).c_str());
  std::abort();
}

std::span<const SimplexId> ExplicitStructure::Reader::Row(Relation r, SimplexId s) const {
  const Stored& st = owner_->stored_[Index(r)];
  if (!st.present) MissingRelation(r);
  if (FixedSize(r) > 0) {
    return {st.values.data() + size_t(s) * FixedSize(r), size_t(FixedSize(r))};
  }
  return {st.values.data() + st.offsets[s], st.values.data() + st.offsets[s + 1]};
}

std::span<const SimplexId> ExplicitStructure::Reader::EdgeNeighbors(SimplexId e) {
  const auto [a, b] = topology_->edge(e);
  const std::span<const SimplexId> at_a = Row(Relation::kVE, a), at_b = Row(Relation::kVE, b);
  edge_neighbors_.clear();
  // Both rows are ascending and share only e itself.
  std::set_union(at_a.begin(), at_a.end(), at_b.begin(), at_b.end(),
                 std::back_inserter(edge_neighbors_));
  std::erase(edge_neighbors_, e);
  return edge_neighbors_;
}

std::span<const SimplexId> ExplicitStructure::Reader::TriangleNeighbors(SimplexId f) {
  triangle_neighbors_.clear();
  for (SimplexId e : Row(Relation::kFE, f)) {
    const std::span<const SimplexId> around = Row(Relation::kEF, e);
    triangle_neighbors_.insert(triangle_neighbors_.end(), around.begin(), around.end());
  }
  std::sort(triangle_neighbors_.begin(), triangle_neighbors_.end());
  triangle_neighbors_.erase(std::unique(triangle_neighbors_.begin(), triangle_neighbors_.end()),
                            triangle_neighbors_.end());
  std::erase(triangle_neighbors_, f);
  return triangle_neighbors_;
}

absl::StatusOr<std::unique_ptr<ExplicitStructure>> ExplicitStructure::Build(
    std::shared_ptr<const Topology> topology, const Options& options, const Progress& progress) {
  constexpr std::string_view kPhase = "precompute";
  auto structure = std::unique_ptr<ExplicitStructure>(new ExplicitStructure(topology));
  structure->relations_ = options.relations;
  const Topology& topo = *topology;
  for (Relation r : AllRelations()) {
    if (options.relations.Contains(r) && NeedsFaces(r) && !topo.has_faces()) {
      return absl::FailedPreconditionError(
          absl::StrCat("explicit structure: relation ", std::string(RelationName(r)),
                       " needs edges and triangles, and the topology was built without them"));
    }
  }
  const int threads = options.threads > 0 ? options.threads : DefaultThreads();
  const int32_t nb = topo.num_blocks();
  std::vector<BlockScratch> scratch(threads);
  int computed = 0, to_compute = 0;
  for (Relation r : AllRelations()) to_compute += options.relations.Contains(r) && !IsStatic(r);
  // One relation at a time: compute every block, then concatenate, so the transient copy is
  // never more than one relation.
  for (Relation r : AllRelations()) {
    if (!options.relations.Contains(r) || IsStatic(r)) continue;
    RETURN_IF_ERROR(progress.Update(kPhase, double(computed++) / to_compute));
    std::vector<RelationBlock> blocks(nb);
    ParallelFor(nb, threads, [&](int64_t b, int thread) {
      if (progress.stopped()) return;  // the blocks left are never read
      blocks[b] = ComputeBlockRelation(topo, r, static_cast<int32_t>(b), scratch[thread]);
    });
    RETURN_IF_ERROR(progress.status(kPhase));
    Stored& st = structure->stored_[Index(r)];
    st.present = true;
    std::vector<int64_t> value_begin(nb + 1, 0);
    for (int32_t b = 0; b < nb; ++b) value_begin[b + 1] = value_begin[b] + blocks[b].values.size();
    if (value_begin[nb] > INT32_MAX) {
      return absl::ResourceExhaustedError("explicit structure: a relation exceeds 2^31 entries");
    }
    st.values.resize(value_begin[nb]);
    const bool csr = FixedSize(r) == 0;
    if (csr) st.offsets.resize(size_t(topo.num_simplices(SourceDimension(r))) + 1);
    ParallelFor(nb, threads, [&](int64_t b, int) {
      RelationBlock& rb = blocks[b];
      std::copy(rb.values.begin(), rb.values.end(), st.values.begin() + value_begin[b]);
      if (csr) {
        for (SimplexId i = 0; i < rb.count; ++i) {
          st.offsets[rb.first + i] = static_cast<SimplexId>(value_begin[b] + rb.offsets[i]);
        }
      }
      rb = RelationBlock();
    });
    if (csr) st.offsets.back() = static_cast<SimplexId>(value_begin[nb]);
  }
  for (Relation r : AllRelations()) {
    if (IsStatic(r)) structure->stored_[Index(r)].present = true;
  }
  RETURN_IF_ERROR(progress.Update(kPhase, 1));
  return structure;
}

MemoryStats ExplicitStructure::memory() const {
  MemoryStats m;
  m.static_bytes = topology_->bytes().total();
  for (const Stored& st : stored_) {
    m.relation_bytes += int64_t(st.offsets.capacity() + st.values.capacity()) * sizeof(SimplexId);
  }
  m.relation_peak_bytes = m.relation_bytes;
  return m;
}

}  // namespace actopo
