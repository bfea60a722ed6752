#include "server/algorithms/critical_points.h"

#include <algorithm>
#include <array>
#include <mutex>

#include "absl/strings/str_cat.h"
#include "server/algorithms/digest.h"
#include "server/algorithms/link_components.h"
#include "server/core/actopo_structure.h"
#include "server/core/compact_structure.h"
#include "server/core/explicit_structure.h"
#include "server/core/link_edges.h"
#include "server/core/structures.h"

namespace actopo {
namespace {

struct Classified {
  CriticalType type = CriticalType::kRegular;
  bool on_boundary = false;
};

// Per consumer, reused across vertices.
struct ClassifyScratch {
  LinkComponents link_components;
  std::vector<uint8_t> known_on_boundary;  // per link vertex: an end of a boundary triangle
  LinkEdgeCounter link;
};

template <class Reader>
Classified Classify(Reader& reader, SimplexId v, std::span<const SimplexId> order,
                    const CriticalPointsOptions& options, ClassifyScratch& scratch) {
  // The link's vertices are numbered from the star itself, not looked up in VV, which then need
  // not be computed at all.
  LinkComponents& components = scratch.link_components;
  components.Scan(reader, v, order);
  const std::span<const SimplexId> neighbors = components.neighbors();
  const size_t n = neighbors.size();
  // v's own boundary flag from the link edges of the star scanned here anyway, not from VB:
  // VB is read only for the neighbours of boundary vertices, and localized structures compute it
  // only for blocks near the boundary.
  LinkEdgeCounter& link = scratch.link;
  link.Reset(n);
  for (const std::array<int, 3>& local : components.triangles()) {
    link.AddTriangle(size_t(local[0]), size_t(local[1]), size_t(local[2]));
  }
  Classified out;
  out.on_boundary = link.AnyOnce();
  int lower = 0, upper = 0;
  for (size_t i = 0; i < n; ++i) {
    if (components.IsRepresentative(i)) (components.below(i) ? lower : upper)++;
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
    // TTK's rule: on which sides of v its boundary neighbours lie. The ends of v's boundary
    // triangles are boundary vertices without asking VB, and they usually lie on both sides
    // already (v is not an extremum of the boundary surface): VB is read only for the other
    // neighbours, and only until both sides are seen, so localized structures compute it for
    // the few blocks around the boundary surface's extrema instead of every block the
    // boundary crosses.
    std::vector<uint8_t>& known = scratch.known_on_boundary;
    known.assign(n, 0);
    link.MarkOnceEnds(known);
    bool lower_on_boundary = false, upper_on_boundary = false;
    for (size_t i = 0; i < n; ++i) {
      if (known[i]) (components.below(i) ? lower_on_boundary : upper_on_boundary) = true;
    }
    for (size_t i = 0; i < n && !(lower_on_boundary && upper_on_boundary); ++i) {
      if (known[i] || !reader.vertex_on_boundary(neighbors[i])) continue;
      (components.below(i) ? lower_on_boundary : upper_on_boundary) = true;
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

RelationSet CriticalPointsDeclared() { return {Relation::kVT, Relation::kVB}; }
RelationSet CriticalPointsSwept() { return {Relation::kVT}; }

template <TopologicalStructure Structure>
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

#define ACTOPO_INSTANTIATE(S)                                      \
  template absl::StatusOr<CriticalPointsResult> RunCriticalPoints( \
      S&, std::span<const SimplexId>, const CriticalPointsOptions&, const RunContext&);
ACTOPO_FOR_EACH_STRUCTURE(ACTOPO_INSTANTIATE)
#undef ACTOPO_INSTANTIATE

}  // namespace actopo
