#include "server/algorithms/critical_points.h"

#include <algorithm>
#include <mutex>

#include "absl/strings/str_cat.h"
#include "server/algorithms/digest.h"
#include "server/core/actopo_structure.h"
#include "server/core/compact_structure.h"
#include "server/core/explicit_structure.h"
#include "server/core/link_edges.h"

namespace actopo {
namespace {

// Union-find over a vertex's link vertices (a few tens): flat arrays reused across vertices.
class LinkComponents {
 public:
  void Reset(size_t n) {
    parent_.resize(n);
    for (size_t i = 0; i < n; ++i) parent_[i] = static_cast<int>(i);
  }
  int Find(int x) {
    while (parent_[x] != x) x = parent_[x] = parent_[parent_[x]];
    return x;
  }
  void Union(int a, int b) { parent_[Find(a)] = Find(b); }

 private:
  std::vector<int> parent_;
};

// Per consumer, reused across vertices.
struct ClassifyScratch {
  LinkComponents components;
  std::vector<SimplexId> neighbors;
  LinkEdgeCounter link;
};

struct Classified {
  CriticalType type = CriticalType::kRegular;
  bool on_boundary = false;
};

template <class Reader>
Classified Classify(Reader& reader, SimplexId v, std::span<const SimplexId> order,
                    const CriticalPointsOptions& options, ClassifyScratch& scratch) {
  // Copy: the boundary rule below reads other vertices' VV-adjacent relations.
  std::vector<SimplexId>& neighbors = scratch.neighbors;
  const auto vv = reader.vertex_neighbors(v);
  neighbors.assign(vv.begin(), vv.end());
  const size_t n = neighbors.size();
  const SimplexId ov = order[v];
  LinkComponents& uf = scratch.components;
  uf.Reset(n);
  // v's own boundary flag from the link edges of the star scanned here anyway, not from VB:
  // VB is read only for the neighbours of boundary vertices, and localized structures compute it
  // only for blocks near the boundary.
  LinkEdgeCounter& link = scratch.link;
  link.Reset(n);
  for (SimplexId t : reader.vertex_star(v)) {
    int local[3];
    bool lower[3];
    int m = 0;
    for (SimplexId w : reader.tetrahedron_vertices(t)) {
      if (w == v) continue;
      local[m] = int(std::lower_bound(neighbors.begin(), neighbors.end(), w) - neighbors.begin());
      lower[m++] = order[w] < ov;
    }
    for (int i = 0; i < 3; ++i) {
      for (int j = i + 1; j < 3; ++j) {
        if (lower[i] == lower[j]) uf.Union(local[i], local[j]);
      }
    }
    link.AddTriangle(size_t(local[0]), size_t(local[1]), size_t(local[2]));
  }
  Classified out;
  out.on_boundary = link.AnyOnce();
  int lower = 0, upper = 0;
  for (size_t i = 0; i < n; ++i) {
    if (uf.Find(int(i)) != int(i)) continue;
    (order[neighbors[i]] < ov ? lower : upper)++;
  }
  if (lower == 0 && upper == 1) {
    out.type = CriticalType::kMinimum;
  } else if (lower == 1 && upper == 0) {
    out.type = CriticalType::kMaximum;
  } else if (lower == 2 && upper == 1) {
    out.type = CriticalType::kSaddle1;
  } else if (lower == 1 && upper == 2) {
    out.type = CriticalType::kSaddle2;
  } else if (lower != 1 || upper != 1) {
    out.type = CriticalType::kDegenerate;
  } else if (options.boundary_rule == BoundaryRule::kTtk && out.on_boundary) {
    bool lower_on_boundary = false, upper_on_boundary = false;
    for (SimplexId w : neighbors) {
      if (!reader.vertex_on_boundary(w)) continue;
      (order[w] < ov ? lower_on_boundary : upper_on_boundary) = true;
    }
    if (upper_on_boundary && !lower_on_boundary) out.type = CriticalType::kSaddle1;
    if (lower_on_boundary && !upper_on_boundary) out.type = CriticalType::kSaddle2;
  }
  return out;
}

}  // namespace

std::string CriticalPointsResult::VerticesDigest() const {
  StreamedText text;
  for (const CriticalPoint& p : points) {
    absl::StrAppend(&text.buffer(), p.vertex, " ", int(p.type), "\n");
    text.Flush();
  }
  return text.HexDigest();
}

RelationSet CriticalPointsDeclared() { return {Relation::kVV, Relation::kVT, Relation::kVB}; }
RelationSet CriticalPointsSwept() { return {Relation::kVV, Relation::kVT}; }

template <class Structure>
absl::StatusOr<CriticalPointsResult> RunCriticalPoints(Structure& structure,
                                                       std::span<const SimplexId> order,
                                                       const CriticalPointsOptions& options,
                                                       const RunContext& context) {
  const Topology& topo = structure.topology();
  std::mutex mu;
  CriticalPointsResult result;
  const absl::Status status = RunOnConsumers(
      context, topo, topo.num_blocks(), [&](int, BlockRange range, WorkTracker& tracker) {
        auto reader = structure.NewReader();
        ClassifyScratch scratch;
        std::vector<CriticalPoint> found;
        for (int32_t b = range.begin; b < range.end; ++b) {
          for (SimplexId v = topo.block_vertex_begin(b); v < topo.block_vertex_begin(b + 1); ++v) {
            const Classified c = Classify(reader, v, order, options, scratch);
            if (c.type == CriticalType::kRegular) continue;
            found.push_back({topo.vertex_input_id(v), c.type, c.on_boundary});
          }
          if (!tracker.Done()) return;
        }
        std::lock_guard<std::mutex> lock(mu);
        result.points.insert(result.points.end(), found.begin(), found.end());
      });
  if (!status.ok()) return status;
  std::sort(result.points.begin(), result.points.end(),
            [](const CriticalPoint& a, const CriticalPoint& b) { return a.vertex < b.vertex; });
  for (const CriticalPoint& p : result.points) ++result.counts[int(p.type)];
  return result;
}

template absl::StatusOr<CriticalPointsResult> RunCriticalPoints(ExplicitStructure&,
                                                                std::span<const SimplexId>,
                                                                const CriticalPointsOptions&,
                                                                const RunContext&);
template absl::StatusOr<CriticalPointsResult> RunCriticalPoints(CompactStructure&,
                                                                std::span<const SimplexId>,
                                                                const CriticalPointsOptions&,
                                                                const RunContext&);
template absl::StatusOr<CriticalPointsResult> RunCriticalPoints(ActopoStructure&,
                                                                std::span<const SimplexId>,
                                                                const CriticalPointsOptions&,
                                                                const RunContext&);

}  // namespace actopo
