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

// Per consumer, reused across vertices.
struct ClassifyScratch {
  LinkComponents components;
  std::vector<SimplexId> neighbors;
  std::vector<uint8_t> link_edges;  // n x n: how often each link edge was met, up to 2
};

// Link edges are counted in a square table up to this many link vertices; past it (rare), the
// vertex's boundary flag is read from VB.
constexpr size_t kMaxCountedLink = 64;

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
  // v is on the boundary iff a triangle of its star lies in one tetrahedron only, i.e. one of
  // its link edges (two other vertices of a star tetrahedron) is met once. The star is scanned
  // here anyway, so v's own flag costs a table, not VB: VB is read only for the neighbours of
  // boundary vertices, and localized structures compute it only for blocks near the boundary.
  const bool count_link = n <= kMaxCountedLink;
  std::vector<uint8_t>& link = scratch.link_edges;
  if (count_link) link.assign(n * n, 0);
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
        if (count_link) {
          const size_t a = size_t(std::min(local[i], local[j]));
          const size_t b = size_t(std::max(local[i], local[j]));
          uint8_t& seen = link[a * n + b];
          seen = seen < 2 ? seen + 1 : 2;
        }
      }
    }
  }
  Classified out;
  out.on_boundary = count_link ? std::find(link.begin(), link.end(), uint8_t{1}) != link.end()
                               : reader.vertex_on_boundary(v);
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
