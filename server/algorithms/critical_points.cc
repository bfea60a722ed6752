#include "server/algorithms/critical_points.h"

#include <algorithm>
#include <mutex>

#include "absl/strings/str_cat.h"
#include "server/algorithms/digest.h"
#include "server/core/actopo_structure.h"
#include "server/core/compact_structure.h"
#include "server/core/explicit_structure.h"

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

template <class Reader>
CriticalType Classify(Reader& reader, SimplexId v, std::span<const SimplexId> order,
                      const CriticalPointsOptions& options, LinkComponents& uf,
                      std::vector<SimplexId>& neighbors) {
  // Copy: the boundary rule below reads other vertices' VV-adjacent relations.
  const auto vv = reader.vertex_neighbors(v);
  neighbors.assign(vv.begin(), vv.end());
  const SimplexId ov = order[v];
  uf.Reset(neighbors.size());
  auto local = [&](SimplexId w) {
    return int(std::lower_bound(neighbors.begin(), neighbors.end(), w) - neighbors.begin());
  };
  for (SimplexId t : reader.vertex_star(v)) {
    const auto tv = reader.tetrahedron_vertices(t);
    SimplexId other[3];
    int n = 0;
    for (SimplexId w : tv) {
      if (w != v) other[n++] = w;
    }
    for (int i = 0; i < 3; ++i) {
      for (int j = i + 1; j < 3; ++j) {
        if ((order[other[i]] < ov) == (order[other[j]] < ov)) {
          uf.Union(local(other[i]), local(other[j]));
        }
      }
    }
  }
  int lower = 0, upper = 0;
  for (size_t i = 0; i < neighbors.size(); ++i) {
    if (uf.Find(int(i)) != int(i)) continue;
    (order[neighbors[i]] < ov ? lower : upper)++;
  }
  if (lower == 0 && upper == 1) return CriticalType::kMinimum;
  if (lower == 1 && upper == 0) return CriticalType::kMaximum;
  if (lower == 2 && upper == 1) return CriticalType::kSaddle1;
  if (lower == 1 && upper == 2) return CriticalType::kSaddle2;
  if (lower != 1 || upper != 1) return CriticalType::kDegenerate;
  if (options.boundary_rule == BoundaryRule::kNone || !reader.vertex_on_boundary(v)) {
    return CriticalType::kRegular;
  }
  bool lower_on_boundary = false, upper_on_boundary = false;
  for (SimplexId w : neighbors) {
    if (!reader.vertex_on_boundary(w)) continue;
    (order[w] < ov ? lower_on_boundary : upper_on_boundary) = true;
  }
  if (upper_on_boundary && !lower_on_boundary) return CriticalType::kSaddle1;
  if (lower_on_boundary && !upper_on_boundary) return CriticalType::kSaddle2;
  return CriticalType::kRegular;
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
        LinkComponents uf;
        std::vector<SimplexId> neighbors;
        std::vector<CriticalPoint> found;
        for (int32_t b = range.begin; b < range.end; ++b) {
          for (SimplexId v = topo.block_vertex_begin(b); v < topo.block_vertex_begin(b + 1); ++v) {
            const CriticalType type = Classify(reader, v, order, options, uf, neighbors);
            if (type == CriticalType::kRegular) continue;
            found.push_back({topo.vertex_input_id(v), type, reader.vertex_on_boundary(v)});
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
