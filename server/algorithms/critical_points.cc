#include "server/algorithms/critical_points.h"

#include <algorithm>
#include <array>
#include <bit>
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
  std::vector<SimplexId> representatives;
  std::vector<uint8_t> known_on_boundary;  // per link vertex: an end of a boundary triangle
  LinkEdgeCounter link;
};

// TTK's type from the numbers of lower and upper link components; regular for one of each.
CriticalType TypeOf(size_t lower, size_t upper) {
  if (lower == 0 && upper == 1) return CriticalType::kMinimum;
  if (lower == 1 && upper == 0) return CriticalType::kMaximum;
  if (lower == 2 && upper == 1) return CriticalType::kSaddle1;
  if (lower == 1 && upper == 2) return CriticalType::kSaddle2;
  if (lower != 1 || upper != 1) return CriticalType::kDegenerate;
  return CriticalType::kRegular;
}

// TTK's rule for a regular vertex on the boundary: on which sides of v its boundary neighbours
// lie. The ends of v's boundary triangles (`end(i)` for link vertex i of `n`) are boundary
// vertices without asking VB, and they usually lie on both sides already (v is not an extremum
// of the boundary surface): VB is read only for the other neighbours, and only until both sides
// are seen, so localized structures compute it for the few blocks around the boundary surface's
// extrema instead of every block the boundary crosses.
template <class Reader, class End, class Below, class Vertex>
CriticalType BoundaryType(Reader& reader, size_t n, End end, Below below, Vertex vertex) {
  bool lower_on_boundary = false, upper_on_boundary = false;
  for (size_t i = 0; i < n; ++i) {
    if (end(i)) (below(i) ? lower_on_boundary : upper_on_boundary) = true;
  }
  for (size_t i = 0; i < n && !(lower_on_boundary && upper_on_boundary); ++i) {
    if (end(i) || !reader.vertex_on_boundary(vertex(i))) continue;
    (below(i) ? lower_on_boundary : upper_on_boundary) = true;
  }
  if (upper_on_boundary && !lower_on_boundary) return CriticalType::kSaddle1;
  if (lower_on_boundary && !upper_on_boundary) return CriticalType::kSaddle2;
  return CriticalType::kRegular;
}

// A link of at most 63 vertices (all but a few) as bit masks: both sides' components and the
// boundary triangles' ends from one reading of the star.
template <class Reader>
Classified ClassifyMasked(Reader& reader, const CriticalPointsOptions& options,
                          ClassifyScratch& scratch) {
  LinkComponents& components = scratch.link_components;
  std::vector<SimplexId>& reps = scratch.representatives;
  components.MaskedRepresentatives(/*lower=*/true, reps);
  const size_t lower = reps.size();
  components.MaskedRepresentatives(/*lower=*/false, reps);
  Classified out{.type = TypeOf(lower, reps.size())};
  const uint64_t ends = components.MaskedBoundaryEnds();
  out.on_boundary = ends != 0;
  if (out.type == CriticalType::kRegular && options.boundary_rule == BoundaryRule::kTtk &&
      out.on_boundary) {
    // Link vertex i is bit i + 1: bit 0 is v itself.
    const uint64_t below = components.MaskedSide(/*lower=*/true) >> 1;
    const uint64_t link =
        (components.MaskedSide(/*lower=*/true) | components.MaskedSide(/*lower=*/false)) >> 1;
    out.type = BoundaryType(
        reader, size_t(std::bit_width(link)),
        [&](size_t i) { return ((ends >> (i + 1)) & 1) != 0; },
        [&](size_t i) { return ((below >> i) & 1) != 0; },
        [&](size_t i) { return components.MaskedVertex(int(i + 1)); });
  }
  return out;
}

// Any link: numbered from the star itself and joined with a union-find, its boundary from the
// link edges counted in a table.
template <class Reader>
Classified ClassifyGeneral(Reader& reader, SimplexId v, std::span<const SimplexId> order,
                           const CriticalPointsOptions& options, ClassifyScratch& scratch) {
  LinkComponents& components = scratch.link_components;
  components.Scan(reader, v, order);
  const std::span<const SimplexId> neighbors = components.neighbors();
  const size_t n = neighbors.size();
  LinkEdgeCounter& link = scratch.link;
  link.Reset(n);
  for (const std::array<int, 3>& local : components.triangles()) {
    link.AddTriangle(size_t(local[0]), size_t(local[1]), size_t(local[2]));
  }
  size_t lower = 0, upper = 0;
  for (size_t i = 0; i < n; ++i) {
    if (components.IsRepresentative(i)) (components.below(i) ? lower : upper)++;
  }
  Classified out{.type = TypeOf(lower, upper), .on_boundary = link.AnyOnce()};
  if (out.type == CriticalType::kRegular && options.boundary_rule == BoundaryRule::kTtk &&
      out.on_boundary) {
    std::vector<uint8_t>& known = scratch.known_on_boundary;
    known.assign(n, 0);
    link.MarkOnceEnds(known);
    out.type = BoundaryType(
        reader, n, [&](size_t i) { return known[i] != 0; },
        [&](size_t i) { return components.below(i); }, [&](size_t i) { return neighbors[i]; });
  }
  return out;
}

// v's own boundary flag comes from the link edges of the star read anyway, not from VB: VB is
// read only for the neighbours of boundary vertices, and localized structures compute it only
// for blocks near the boundary. The link's vertices are numbered from the star itself, not
// looked up in VV, which then need not be computed at all.
template <class Reader>
Classified Classify(Reader& reader, SimplexId v, std::span<const SimplexId> order,
                    const CriticalPointsOptions& options, ClassifyScratch& scratch) {
  if (scratch.link_components.ScanMasked(reader, v, order, LinkComponents::kBothSides)) {
    return ClassifyMasked(reader, options, scratch);
  }
  return ClassifyGeneral(reader, v, order, options, scratch);
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
