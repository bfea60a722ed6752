#include "server/algorithms/morse_smale.h"

#include <algorithm>
#include <atomic>
#include <iterator>
#include <optional>

#include "absl/container/flat_hash_set.h"
#include "absl/strings/str_cat.h"
#include "server/algorithms/digest.h"
#include "server/algorithms/gradient_paths.h"
#include "server/algorithms/pair_keys.h"
#include "server/algorithms/prefetch_off.h"
#include "server/core/actopo_structure.h"
#include "server/core/compact_structure.h"
#include "server/core/explicit_structure.h"
#include "server/core/parallel.h"
#include "server/core/status_macros.h"
#include "server/core/structures.h"
#include "server/core/sync.h"
#include "server/core/trace.h"

namespace actopo {
namespace {

// Descending 1-separatrices: from each 1-saddle's two vertices down the vertex-edge pairs to a
// minimum. Needs no relation.
void DescendingSeparatrices(const Topology& topo, const GradientField& g,
                            std::span<const SimplexId> saddles, std::vector<Separatrix>& out) {
  for (SimplexId e : saddles) {
    for (SimplexId start : topo.edge(e)) {
      Separatrix s{SeparatrixType::kDescending, {1, e}, {}, {e}};
      s.path.push_back(start);  // a vertex, then its edge, then the next vertex ...
      WalkDown(topo, g, start, [&](SimplexId edge, SimplexId next) {
        s.path.push_back(edge);
        s.path.push_back(next);
      });
      s.destination = s.cell(s.path.size() - 1);
      s.path.shrink_to_fit();  // as in SaddleConnectors
      out.push_back(std::move(s));
    }
  }
}

// Whether tetrahedron tv has vertices b and c.
bool Contains(std::span<const SimplexId, 4> tv, SimplexId b, SimplexId c) {
  int found = 0;
  for (SimplexId v : tv) found += (v == b) + (v == c);
  return found == 2;
}

// Which edges and triangles are critical, one bit each. The gradient keeps only the pairings
// the paths follow (GradientArrays::kPaths: vertex -> edge, edge -> triangle; kPersistence adds
// tetrahedron -> triangle, for a caller's gradient); a triangle's edge comes from its edges'
// pairings (DownEdge). The arrays left out are 4 bytes per edge and 8 per triangle.
class CriticalSaddles {
 public:
  CriticalSaddles(const Topology& topo, const std::array<std::vector<SimplexId>, 4>& critical)
      : edges_(size_t(topo.num_edges()), false), triangles_(size_t(topo.num_triangles()), false) {
    for (SimplexId e : critical[1]) edges_[e] = true;
    for (SimplexId f : critical[2]) triangles_[f] = true;
  }
  bool edge(SimplexId e) const { return edges_[e]; }
  bool triangle(SimplexId f) const { return triangles_[f]; }

 private:
  std::vector<bool> edges_, triangles_;
};

// The work after the gradient that reads relations, per item, on one consumer's reader.
template <class Reader>
class Builder {
 public:
  // `next_up`, for AscendingSeparatrices: per tetrahedron, the next one up (RecordUpLinks), -1 when
  // its path leaves through the boundary, a maximum's LinkCode. Those paths read no pairing.
  Builder(Reader& reader, const GradientField& gradient, const CriticalSaddles& saddles,
          std::span<const uint8_t> input_corners, std::span<const SimplexId> next_up = {})
      : r_(reader),
        topo_(reader.topology()),
        g_(gradient),
        saddles_(saddles),
        input_corners_(input_corners),
        next_up_(next_up) {}

  // The ascending 1-separatrices of 2-saddle f: one per tetrahedron of its star (in TTK's order)
  // whose path ends at a maximum.
  // `star`: f's tetrahedra (TriangleTetrahedra).
  void AscendingSeparatrices(SimplexId f, std::span<const SimplexId> star,
                             std::vector<Separatrix>& out) {
    star_.assign(star.begin(), star.end());
    std::sort(star_.begin(), star_.end(), [&](SimplexId a, SimplexId b) {
      return topo_.tetrahedron_input_id(a) < topo_.tetrahedron_input_id(b);
    });
    for (SimplexId t : star_) {
      Separatrix s{SeparatrixType::kAscending, {2, f}, {}, {f}};
      if (AscendingPath(t, s.path)) {
        s.destination = s.cell(s.path.size() - 1);
        s.path.shrink_to_fit();  // as in SaddleConnectors
        out.push_back(std::move(s));
      }
    }
  }

  // The saddle connectors ending at 2-saddle s2: its descending wall (triangles reached through
  // the up-pairs of their edges) and, from each 1-saddle on it, the path up through the wall.
  void SaddleConnectors(SimplexId s2, std::vector<Separatrix>& out) {
    DescendingWall(s2);
    for (SimplexId s1 : wall_saddles_) {
      Separatrix s{SeparatrixType::kSaddleConnector, {1, s1}, {2, s2}, {}};
      // Ends at s2: a triangle (odd length: an edge first, then triangle and edge in turn).
      if (PathThroughWall(s1, s.path) && s.path.size() % 2 == 0 && s.path.back() == s2) {
        // The result holds every path to the end, so none keeps the slack of its growth.
        s.path.shrink_to_fit();
        out.push_back(std::move(s));
      }
    }
  }

  // One read of vertex a's star: returns a's first tetrahedron in input order (-1 for an unused
  // vertex), and sets up[t] to the next tetrahedron up (across its paired triangle; -1 when that
  // triangle is on the boundary) for each tetrahedron t paired with a triangle whose lowest
  // vertex is a. That triangle's star lies in a's. Every paired triangle has one lowest vertex,
  // so a pass over every vertex sets each non-critical tetrahedron's entry once, and a block's
  // pass reads only its own vertices' stars (following each tetrahedron's triangle to its lowest
  // vertex, in whichever block, would compute other blocks' VT again).
  SimplexId RecordUpLinks(SimplexId a, std::span<SimplexId> up) {
    const auto star = r_.vertex_star(a);
    if (star.empty()) return -1;
    const SimplexId first_triangle = topo_.vertex_first_triangle(a);
    const SimplexId end_triangle = topo_.vertex_first_triangle(a + 1);
    SimplexId first = star[0];
    // The star's tuples, decoded once for the searches below (a few per star).
    star_tuples_.resize(star.size());
    for (size_t i = 0; i < star.size(); ++i) star_tuples_[i] = topo_.tetrahedron(star[i]);
    for (SimplexId t : star) {
      if (topo_.tetrahedron_input_id(t) < topo_.tetrahedron_input_id(first)) first = t;
      if (g_.IsCritical(3, t)) continue;
      const SimplexId f = g_.down[3][t];
      if (f < first_triangle || f >= end_triangle) continue;  // another vertex's triangle
      const SimplexId b = topo_.edge_upper(topo_.triangle_edge(f), a);
      const SimplexId c = topo_.triangle_third(f, a);
      up[t] = LinkCode::kBoundary;
      for (size_t i = 0; i < star.size(); ++i) {
        if (star[i] != t && Contains(star_tuples_[i], b, c)) {
          up[t] = star[i];
          break;
        }
      }
    }
    return first;
  }

  // The tetrahedra of f = (a, b, c) (one on the boundary, else two), ascending. Those whose
  // fourth vertex is above a have a as their lowest vertex: the static encoding lists them
  // together (TriangleTetrahedraInRun), so no relation is read when they are all of f's (on a
  // mesh where a triangle has at most two). Only when some are missing (their lowest vertex is
  // below a) is a's star read: a vertex star costs a quarter of a triangle star to compute per
  // block, and walls would compute a block's triangle stars many times over. The run saves few
  // block computations, as a block's star is computed once any of its triangles misses.
  std::span<const SimplexId> TriangleTetrahedra(SimplexId f) {
    triangle_star_.clear();
    std::array<SimplexId, 2> in_run;
    if (const int n = topo_.TriangleTetrahedraInRun(f, in_run); n >= 0) {
      triangle_star_.assign(in_run.begin(), in_run.begin() + n);
      return triangle_star_;
    }
    const auto [a, b, c] = topo_.triangle(f);
    for (SimplexId t : r_.vertex_star(a)) {
      if (Contains(topo_.tetrahedron(t), b, c)) triangle_star_.push_back(t);
    }
    return triangle_star_;
  }

 private:
  // tet -> its paired triangle -> the next tetrahedron ... until a maximum. False when the path
  // leaves through the boundary. The paired triangle is the one the two tetrahedra share, so
  // the tetrahedron -> triangle pairing is not kept for these paths (4 bytes per tetrahedron).
  bool AscendingPath(SimplexId tet, std::vector<SimplexId>& path) {
    path.push_back(tet);  // a tetrahedron, then its triangle, then the next tetrahedron ...
    return ClimbLinks(next_up_, tet, [&](SimplexId from, SimplexId to) {
             path.push_back(SharedTriangle(from, to));
             path.push_back(to);
           }) != LinkCode::kBoundary;
  }

  SimplexId SharedTriangle(SimplexId t, SimplexId u) const {
    const auto tv = topo_.tetrahedron(t), uv = topo_.tetrahedron(u);
    std::array<SimplexId, 3> shared{};
    int n = 0;
    for (SimplexId v : tv) {
      if (n < 3 && std::find(uv.begin(), uv.end(), v) != uv.end()) shared[n++] = v;
    }
    return topo_.FindTriangle(shared[0], shared[1], shared[2]);
  }

  // The wall of s2 and, for the paths through it, which wall triangles lie around each edge.
  // Walls wander across many blocks (a structure computing by block would compute each block's
  // edge-triangles many times over), so nothing here reads a block relation: a triangle's edges
  // come from the static encoding (FindEdge), and the wall's own (edge, triangle) pairs stand in
  // for the edge-triangle relation restricted to the wall. A triangle's own down edge (the one
  // paired with it) gets no pair: a path comes down that edge from the triangle, never up it.
  void DescendingWall(SimplexId s2) {
    for (SimplexId f : wall_) in_wall_[f] = false;  // the previous wall's marks
    if (in_wall_.empty()) in_wall_.resize(size_t(topo_.num_triangles()), false);
    wall_.clear();
    wall_saddles_.clear();
    wall_edges_.clear();
    in_wall_[s2] = true;
    wall_.push_back(s2);
    for (size_t i = 0; i < wall_.size(); ++i) {  // breadth first: wall_ is the queue
      const SimplexId f = wall_[i];
      for (SimplexId e : topo_.triangle_edges(f)) {
        const SimplexId paired = g_.up[1][e];
        if (paired == f) continue;
        wall_edges_.push_back(uint64_t(e) << 32 | uint64_t(f));
        if (saddles_.edge(e)) wall_saddles_.push_back(e);
        if (paired >= 0 && !in_wall_[paired]) {
          in_wall_[paired] = true;
          wall_.push_back(paired);
        }
      }
    }
    std::sort(wall_saddles_.begin(), wall_saddles_.end());
    wall_saddles_.erase(std::unique(wall_saddles_.begin(), wall_saddles_.end()),
                        wall_saddles_.end());
    SortPairKeys(wall_edges_, sort_scratch_);
  }

  // The wall's triangles around edge e but the one paired with it, ascending (the
  // edge-triangle row's order), as keys: WallTriangle(key) is the triangle.
  std::span<const uint64_t> WallTriangles(SimplexId e) const {
    const uint64_t key = uint64_t(e) << 32;
    const auto first = std::lower_bound(wall_edges_.begin(), wall_edges_.end(), key);
    return {first, std::lower_bound(first, wall_edges_.end(), key + (uint64_t(1) << 32))};
  }
  static SimplexId WallTriangle(uint64_t key) { return SimplexId(key & 0xffffffffu); }

  // From 1-saddle s1 up through the current wall: triangle -> its paired edge -> the wall
  // triangle around that edge other than the previous one (the last in TTK's edge-triangle
  // order when several) ... until a critical cell or a dead end. False if s1 touches no wall
  // triangle.
  bool PathThroughWall(SimplexId s1, std::vector<SimplexId>& path) {
    path.push_back(s1);  // an edge, then triangle and edge in turn
    SimplexId cur = -1;
    candidates_.clear();
    for (const uint64_t key : WallTriangles(s1)) {
      const SimplexId f = WallTriangle(key);
      if (saddles_.triangle(f)) {
        path.push_back(f);
        return true;
      }
      candidates_.push_back(f);
    }
    if (candidates_.empty()) return false;
    cur = LastInTtkOrder(candidates_);
    // A valid gradient has no cycle here; the bound only guards against looping forever.
    for (size_t steps = 0; steps <= wall_.size(); ++steps) {
      path.push_back(cur);
      if (saddles_.triangle(cur)) return true;
      const SimplexId e = DownEdge(cur);
      path.push_back(e);
      if (saddles_.edge(e)) return true;
      candidates_.clear();  // cur, paired with e, is not among them
      for (const uint64_t key : WallTriangles(e)) candidates_.push_back(WallTriangle(key));
      if (candidates_.empty()) return true;  // dead end: the path stops at edge e
      cur = LastInTtkOrder(candidates_);
    }
    return true;
  }

  // The edge paired with wall triangle f (every wall triangle but its saddle is paired with one
  // of its edges): the one of its three edges whose pairing points back at it.
  // Edges are looked up only until it is found.
  SimplexId DownEdge(SimplexId f) const {
    const SimplexId ab = topo_.triangle_edge(f);
    if (g_.up[1][ab] == f) return ab;
    const SimplexId a = topo_.edge_lowest(ab), b = topo_.edge_upper(ab, a);
    const SimplexId c = topo_.triangle_third(f, a);
    if (const SimplexId ac = topo_.FindEdge(a, c); g_.up[1][ac] == f) return ac;
    const SimplexId bc = topo_.FindEdge(b, c);
    return g_.up[1][bc] == f ? bc : -1;
  }

  // TTK numbers triangles by first appearance over tetrahedra in input order, faces (v0 v1 v2),
  // (v1 v2 v3), (v2 v3 v0), (v3 v0 v1) of the tetrahedron as given.
  uint64_t TtkTriangleRank(SimplexId f) {
    const auto fv = topo_.triangle(f);
    uint64_t best = UINT64_MAX;
    for (SimplexId t : TriangleTetrahedra(f)) {
      const auto tv = topo_.tetrahedron(t);
      int corner = 0;  // of the sorted tuple, the vertex not in f
      while (tv[corner] == fv[0] || tv[corner] == fv[1] || tv[corner] == fv[2]) ++corner;
      const int omitted = (input_corners_[t] >> (2 * corner)) & 3;  // its position as given
      const SimplexId input = topo_.tetrahedron_input_id(t);
      best = std::min(best, uint64_t(input) * 4 + uint64_t((omitted + 1) % 4));
    }
    return best;
  }

  SimplexId LastInTtkOrder(const std::vector<SimplexId>& triangles) {
    if (triangles.size() == 1) return triangles[0];
    SimplexId last = triangles[0];
    uint64_t last_rank = TtkTriangleRank(last);
    for (size_t i = 1; i < triangles.size(); ++i) {
      const uint64_t rank = TtkTriangleRank(triangles[i]);
      if (rank > last_rank) {
        last = triangles[i];
        last_rank = rank;
      }
    }
    return last;
  }

  Reader& r_;
  const Topology& topo_;
  const GradientField& g_;
  const CriticalSaddles& saddles_;
  std::span<const uint8_t> input_corners_;
  std::span<const SimplexId> next_up_;
  std::vector<SimplexId> wall_;         // the current wall's triangles, as found
  std::vector<bool> in_wall_;           // per triangle, whether wall_ holds it (1 bit each)
  std::vector<uint64_t> wall_edges_;    // edge << 32 | wall triangle, sorted
  std::vector<uint64_t> sort_scratch_;  // SortPairKeys's
  std::vector<SimplexId> wall_saddles_, candidates_, star_, triangle_star_;
  std::vector<std::array<SimplexId, 4>> star_tuples_;  // RecordUpLinks's star, decoded
};

// The segmentations' passes cost little per item but cover every vertex and tetrahedron, too
// much for one thread: ranges of this many items on the run's threads.
constexpr int64_t kRange = 1 << 15;

std::vector<SimplexId> ToInputOrder(const Topology& topo, const std::vector<SimplexId>& by_internal,
                                    int threads) {
  std::vector<SimplexId> out(by_internal.size());
  ParallelForRanges(int64_t(by_internal.size()), kRange, threads, [&](int64_t begin, int64_t end) {
    for (SimplexId v = SimplexId(begin); v < end; ++v)
      out[topo.vertex_input_id(v)] = by_internal[v];
  });
  return out;
}

// Per label, how many entries hold it (-1 counts for none).
std::vector<int64_t> LabelSizes(std::span<const SimplexId> labels, size_t num_labels) {
  std::vector<int64_t> sizes(num_labels, 0);
  for (SimplexId l : labels) {
    if (l >= 0) ++sizes[l];
  }
  return sizes;
}

// Follows the chain next(cur) from `start` until known(cur) holds, then gives every cell on the
// way label(cur). Chains from different starts meet, and threads may follow the same stretch at
// once: the labels are relaxed atomics, each written only with its one final value, so whichever
// thread writes first the result is the same. Returns false when the chain is longer than
// `limit` (it closed on itself, which a valid gradient never does); nothing is written then.
template <class Next, class Known>
bool LabelChain(SimplexId start, std::vector<SimplexId>& label, std::vector<SimplexId>& path,
                size_t limit, Next&& next, Known&& known) {
  path.clear();
  SimplexId cur = start;
  SimplexId at = std::atomic_ref<SimplexId>(label[cur]).load(std::memory_order_relaxed);
  while (!known(at)) {
    if (path.size() > limit) return false;
    path.push_back(cur);
    cur = next(cur, at);
    at = std::atomic_ref<SimplexId>(label[cur]).load(std::memory_order_relaxed);
  }
  for (SimplexId p : path)
    std::atomic_ref<SimplexId>(label[p]).store(at, std::memory_order_relaxed);
  return true;
}

// Minima labelled 0.. in ascending input vertex id; each vertex takes its V-path's minimum.
// Needs no relation.
std::vector<SimplexId> DescendingSegmentation(const Topology& topo, const GradientField& g,
                                              std::span<const SimplexId> critical_vertices,
                                              std::vector<int64_t>& sizes, int threads) {
  const SimplexId nv = topo.num_vertices();
  std::vector<SimplexId> minima(critical_vertices.begin(), critical_vertices.end());
  std::sort(minima.begin(), minima.end(), [&](SimplexId a, SimplexId b) {
    return topo.vertex_input_id(a) < topo.vertex_input_id(b);
  });
  std::vector<SimplexId> label(nv, -1);  // internal ids
  if (minima.size() == 1) {
    std::fill(label.begin(), label.end(), 0);  // as TTK: every vertex, used or not
  } else {
    for (size_t i = 0; i < minima.size(); ++i) label[minima[i]] = SimplexId(i);
    // A V-path descends the field, so it ends at a minimum (or the gradient is broken; a path
    // longer than the vertex count then labels nothing and its vertices stay -1).
    const auto across = [&](SimplexId v, SimplexId) { return NextVertexDown(topo, g, v); };
    ParallelForRanges(nv, kRange, threads, [&](int64_t begin, int64_t end) {
      std::vector<SimplexId> path;
      for (SimplexId v = SimplexId(begin); v < end; ++v) {
        LabelChain(v, label, path, size_t(nv), across, [](SimplexId l) { return l >= 0; });
      }
    });
  }
  sizes = LabelSizes(label, minima.size());
  return ToInputOrder(topo, label, threads);
}

// `next` holds per tetrahedron the next one up (RecordUpLinks), -1 at the boundary, or a maximum's
// LinkCode. Follows every path to its end and leaves the labels: the maximum reached, -1 when
// the path leaves through the boundary (or closes on itself, which a valid gradient never
// does). Needs no relation.
void ResolveAscendingLabels(std::vector<SimplexId>& next, int threads) {
  const int64_t n = int64_t(next.size());
  // An entry >= 0 is the next tetrahedron; a code (< 0) is final. LabelChain reads each entry
  // before following it, so an entry another thread has just resolved only ends the chain early.
  ParallelForRanges(n, kRange, threads, [&](int64_t begin, int64_t end) {
    std::vector<SimplexId> path;
    for (SimplexId t = SimplexId(begin); t < end; ++t) {
      const auto up = [](SimplexId, SimplexId at) { return at; };
      const auto code = [](SimplexId at) { return LinkCode::IsEnd(at); };
      if (!LabelChain(t, next, path, size_t(n), up, code)) {
        for (SimplexId p : path) {
          std::atomic_ref<SimplexId>(next[p]).store(LinkCode::kBoundary, std::memory_order_relaxed);
        }
      }
    }
  });
  ParallelForRanges(n, kRange, threads, [&](int64_t begin, int64_t end) {
    for (int64_t t = begin; t < end; ++t) next[t] = LinkCode::Label(next[t]);
  });
}

std::vector<SimplexId> FinalSegmentation(const std::vector<SimplexId>& descending,
                                         const std::vector<SimplexId>& ascending,
                                         int64_t num_maxima, int threads) {
  const auto sparse = [&](size_t v) {
    return descending[v] < 0 || ascending[v] < 0
               ? int64_t(-1)
               : int64_t(descending[v]) * num_maxima + ascending[v];
  };
  // Dense ranks of the distinct sparse ids, -1 included (so it becomes region 0, as in TTK). The
  // regions are few: their ids are collected in a set per chunk of vertices, not in a copy per
  // vertex, then merged and ranked.
  const int64_t n = int64_t(descending.size());
  Mutex mu;
  absl::flat_hash_set<int64_t> seen;
  ParallelForRanges(n, kRange, threads, [&](int64_t begin, int64_t end) {
    absl::flat_hash_set<int64_t> local;
    for (int64_t v = begin; v < end; ++v) local.insert(sparse(size_t(v)));
    MutexLock lock(mu);
    seen.insert(local.begin(), local.end());
  });
  std::vector<int64_t> distinct(seen.begin(), seen.end());
  std::sort(distinct.begin(), distinct.end());
  std::vector<SimplexId> out(descending.size());
  ParallelForRanges(n, kRange, threads, [&](int64_t begin, int64_t end) {
    for (int64_t v = begin; v < end; ++v) {
      out[v] = SimplexId(std::lower_bound(distinct.begin(), distinct.end(), sparse(size_t(v))) -
                         distinct.begin());
    }
  });
  return out;
}

}  // namespace

int64_t MorseSmaleResult::CountSeparatrices(SeparatrixType type) const {
  return std::count_if(separatrices.begin(), separatrices.end(),
                       [&](const Separatrix& s) { return s.type == type; });
}

int64_t MorseSmaleResult::Segments() const {
  int64_t n = 0;
  for (const Separatrix& s : separatrices) n += int64_t(s.path.size()) - 1;
  return n;
}

int64_t MorseSmaleResult::Regions(std::span<const SimplexId> labels) {
  if (labels.empty()) return 0;
  const auto [low, high] = std::minmax_element(labels.begin(), labels.end());
  const int64_t range = int64_t(*high) - *low + 1;
  if (range <= 8 * int64_t(labels.size())) {  // labels are region ids from -1: a bit each
    std::vector<bool> seen(size_t(range), false);
    int64_t distinct = 0;
    for (SimplexId l : labels) {
      const size_t k = size_t(int64_t(l) - *low);
      distinct += !seen[k];
      seen[k] = true;
    }
    return distinct;
  }
  std::vector<SimplexId> distinct(labels.begin(), labels.end());
  std::sort(distinct.begin(), distinct.end());
  return std::unique(distinct.begin(), distinct.end()) - distinct.begin();
}

std::string MorseSmaleResult::SegmentationDigest(std::span<const SimplexId> labels) {
  StreamedText text;
  for (size_t v = 0; v < labels.size(); ++v) {
    absl::StrAppend(&text.buffer(), v, " ", labels[v], "\n");
    text.Flush();
  }
  return text.HexDigest();
}

RelationSet MorseSmaleDeclared() {
  // The gradient's VE, VF, VT. Triangle stars come from vertex stars; the walls read none.
  return {Relation::kVE, Relation::kVF, Relation::kVT};
}

absl::StatusOr<std::vector<uint8_t>> InputCorners(const Topology& topology,
                                                  std::span<const SimplexId> input_tetrahedra) {
  const SimplexId num_tets = topology.num_tetrahedra();
  if (input_tetrahedra.size() != 4 * size_t(num_tets)) {
    return absl::InvalidArgumentError(absl::StrCat("morse-smale: ", input_tetrahedra.size(),
                                                   " tetrahedron vertex ids for ", num_tets,
                                                   " tetrahedra"));
  }
  std::vector<uint8_t> corners(size_t(num_tets), 0);
  std::atomic<SimplexId> mismatch{-1};
  const SimplexId num_vertices = topology.num_vertices();
  ParallelForRanges(num_tets, 1 << 16, DefaultThreads(), [&](int64_t begin, int64_t end) {
    for (SimplexId t = SimplexId(begin); t < end; ++t) {
      const auto sorted = topology.tetrahedron(t);
      const SimplexId* given = &input_tetrahedra[4 * size_t(topology.tetrahedron_input_id(t))];
      uint8_t byte = 0;
      int seen = 0;  // corners of the sorted tuple met, one bit each
      for (int p = 0; p < 4; ++p) {
        if (given[p] < 0 || given[p] >= num_vertices) break;
        const SimplexId v = topology.vertex_internal_id(given[p]);
        for (int k = 0; k < 4; ++k) {
          if (sorted[k] != v || (seen & (1 << k))) continue;
          byte |= uint8_t(p << (2 * k));
          seen |= 1 << k;
          break;
        }
      }
      if (seen != 0xF) {
        mismatch.store(topology.tetrahedron_input_id(t));
        return;
      }
      corners[t] = byte;
    }
  });
  if (const SimplexId t = mismatch.load(); t >= 0) {
    return absl::InvalidArgumentError(
        absl::StrCat("morse-smale: input tetrahedron ", t, " is not the one the topology holds"));
  }
  return corners;
}

// What the ascending paths read of the vertex stars, when the gradient's sweep did not record
// it (AscendingLinks): in one pass over the blocks, while their stars are at hand (RecordUpLinks,
// TriangleTetrahedra), each vertex's first tetrahedron into `vertex_label`, each tetrahedron's next
// one up into `up`, each 2-saddle's tetrahedra into `saddle_tets` (two slots, -1 when on the
// boundary). The separatrices then read no relation: tracing them through vertex stars would
// compute each block's stars again, once per wall through it.
template <TopologicalStructure Structure>
absl::Status ReadAscendingLinks(Structure& structure, const GradientField& g,
                                const CriticalSaddles& critical_saddles,
                                std::span<const uint8_t> input_corners,
                                const std::vector<SimplexId>& saddles, std::vector<SimplexId>& up,
                                std::vector<SimplexId>& vertex_label,
                                std::vector<SimplexId>& saddle_tets, const RunContext& context) {
  const Topology& topo = structure.topology();
  saddle_tets.assign(2 * saddles.size(), -1);
  return RunOnConsumers(
      context, topo, topo.num_blocks(), [&](int, BlockRange range, WorkTracker& tracker) {
        auto reader = structure.NewReader();
        Builder builder(reader, g, critical_saddles, input_corners);
        for (int32_t b = range.begin; b < range.end; ++b) {
          for (SimplexId v = topo.block_vertex_begin(b); v < topo.block_vertex_begin(b + 1); ++v) {
            vertex_label[v] = builder.RecordUpLinks(v, up);
          }
          for (auto i =
                   std::lower_bound(saddles.begin(), saddles.end(), topo.block_triangle_begin(b));
               i != saddles.end() && *i < topo.block_triangle_begin(b + 1); ++i) {
            const auto star = builder.TriangleTetrahedra(*i);
            std::copy(star.begin(), star.end(), saddle_tets.begin() + 2 * (i - saddles.begin()));
          }
          reader.Finished(b);  // both read the stars of b's own vertices
          if (!tracker.Done()) return;
        }
      });
}

// Per 2-saddle, in ascending id: its ascending separatrices and its saddle connectors, on every
// consumer, appended to `separatrices` in that order (all ascending ones, then all connectors).
// Walls differ in size, so saddles go to whichever consumer is free, in runs of ascending ids: a
// wall's ties in TTK's triangle order read vertex stars around it, and runs keep each consumer
// on blocks of its own instead of both computing every block.
template <TopologicalStructure Structure>
absl::Status AppendWalls(Structure& structure, const GradientField& g,
                         const CriticalSaddles& critical_saddles,
                         std::span<const uint8_t> input_corners, std::span<const SimplexId> up,
                         const std::vector<SimplexId>& saddles,
                         const std::vector<SimplexId>& saddle_tets, const RunContext& context,
                         std::vector<Separatrix>& separatrices) {
  const int64_t chunk = std::max<int64_t>(
      1, int64_t(saddles.size()) / (16 * int64_t(std::max(context.consumers, 1))));
  std::vector<std::vector<Separatrix>> ascending(saddles.size()), connectors(saddles.size());
  // Reads follow walls, not blocks: actopo's producers would only compete with the consumers.
  std::optional<PrefetchOff<Structure>> prefetch_off(structure);
  const absl::Status status = RunOnConsumersShared(
      context, int64_t(saddles.size()), chunk, [&](int, ItemQueue& queue, WorkTracker& tracker) {
        auto reader = structure.NewReader();
        Builder builder(reader, g, critical_saddles, input_corners, up);
        int64_t begin, end;
        while (queue.Next(begin, end)) {
          for (int64_t i = begin; i < end; ++i) {
            const SimplexId* star = &saddle_tets[2 * i];
            builder.AscendingSeparatrices(saddles[i], {star, star[1] < 0 ? 1u : 2u}, ascending[i]);
            builder.SaddleConnectors(saddles[i], connectors[i]);
          }
          if (!tracker.Done(end - begin)) return;
        }
      });
  prefetch_off.reset();
  RETURN_IF_ERROR(status);
  size_t total = separatrices.size();
  for (auto* per_saddle : {&ascending, &connectors}) {
    for (const auto& list : *per_saddle) total += list.size();
  }
  separatrices.reserve(total);  // no doubling slack, no old copy beside the new one
  for (auto* per_saddle : {&ascending, &connectors}) {
    for (auto& list : *per_saddle) {
      std::move(list.begin(), list.end(), std::back_inserter(separatrices));
    }
    // Moved-from shells: freed before the segmentations allocate, where the peak is.
    std::vector<std::vector<Separatrix>>().swap(*per_saddle);
  }
  return absl::OkStatus();
}

// The segmentations, once the paths are traced: descending from the gradient (the last reader
// of its pairings, which go before the last arrays come), ascending from `up` (each
// tetrahedron's path up to a maximum's label, -1 if it leaves through the boundary; a vertex
// takes the label of the tetrahedron of its star with the lowest input id, found through
// `vertex_label`), then their product.
void Segment(const Topology& topo, GradientField& g, std::vector<SimplexId>& up,
             std::vector<SimplexId>& vertex_label, size_t maxima, int threads,
             MorseSmaleResult& result) {
  result.descending =
      DescendingSegmentation(topo, g, result.gradient.critical[0], result.minimum_sizes, threads);
  for (auto& pairings : {&g.up, &g.down}) {
    for (Pairings& a : *pairings) Pairings().swap(a);
  }
  ResolveAscendingLabels(up, threads);
  ParallelForRanges(int64_t(vertex_label.size()), kRange, threads, [&](int64_t begin, int64_t end) {
    for (int64_t v = begin; v < end; ++v) {
      if (vertex_label[v] >= 0) vertex_label[v] = up[vertex_label[v]];
    }
  });
  std::vector<SimplexId>().swap(up);  // 4 bytes per tetrahedron, before the last arrays
  result.maximum_sizes = LabelSizes(vertex_label, maxima);
  result.ascending = ToInputOrder(topo, vertex_label, threads);
  result.morse_smale = FinalSegmentation(result.descending, result.ascending,
                                         int64_t(result.maximum_sizes.size()), threads);
}

template <TopologicalStructure Structure>
absl::StatusOr<MorseSmaleResult> RunMorseSmale(Structure& structure,
                                               std::span<const SimplexId> order,
                                               std::span<const uint8_t> input_corners,
                                               const RunContext& context,
                                               std::optional<DiscreteGradientResult> gradient) {
  const Topology& topo = structure.topology();
  if (input_corners.size() != size_t(topo.num_tetrahedra())) {
    return absl::InvalidArgumentError(absl::StrCat("morse-smale: input corners of ",
                                                   input_corners.size(), " tetrahedra for ",
                                                   topo.num_tetrahedra()));
  }
  // Progress: the gradient is the first half, the separatrices and segmentations the rest.
  // The passes after the consumers' phases (segmentations) run on as many threads.
  const int threads = std::max(context.consumers, 1);
  MorseSmaleResult result;
  // Per tetrahedron its next one up (-1 for the critical ones until they are labelled), per
  // vertex its first tetrahedron (in vertex_label until the labels are known), per 2-saddle its
  // tetrahedra: what the ascending separatrices and segmentation read of the vertex stars. The
  // gradient's sweep records them (AscendingLinks) when this run computes the gradient, else
  // ReadAscendingLinks reads them.
  std::vector<SimplexId> up(topo.num_tetrahedra(), -1);
  std::vector<SimplexId> vertex_label(topo.num_vertices(), -1);
  std::vector<SimplexId> saddle_tets;
  const bool linked = !gradient && !topo.has_crowded_triangles();
  AscendingLinks links{up, vertex_label, {}};
  links.saddles.resize(size_t(threads));
  if (gradient) {
    result.gradient = std::move(*gradient);
  } else {
    const GradientArrays arrays = linked ? GradientArrays::kPaths : GradientArrays::kPersistence;
    ASSIGN_OR_RETURN(result.gradient,
                     RunDiscreteGradient(structure, order, context.Slice(0.0, 0.5), arrays, nullptr,
                                         linked ? &links : nullptr));
  }
  GradientField& g = result.gradient.gradient;
  // What the paths do not follow (a caller's gradient may have every array), and the gradient's
  // buffered relations (the end of its sweep; VE and VF, which nothing below reads), freed
  // before the arrays below are allocated, and with them what the caller's phases freed (a
  // simplification's kept neighbours): the peak would be here, the buffer beside `up` and the
  // labels.
  for (auto* unused : {&g.up[2], &g.down[1], &g.down[2]}) Pairings().swap(*unused);
  EndPhase(structure);
  const CriticalSaddles critical_saddles(topo, result.gradient.critical);
  DescendingSeparatrices(topo, g, result.gradient.critical[1], result.separatrices);

  const std::vector<SimplexId>& saddles = result.gradient.critical[2];
  if (linked) {
    ASSIGN_OR_RETURN(saddle_tets, SaddleTetrahedra(links, saddles));
  } else {
    RETURN_IF_ERROR(ReadAscendingLinks(structure, g, critical_saddles, input_corners, saddles, up,
                                       vertex_label, saddle_tets, context.Slice(0.5, 0.6)));
  }
  // The maxima labelled 0.. in ascending input tetrahedron id, in `up` (LinkCode), where the
  // ascending paths below find their ends. Nothing reads the tetrahedron -> triangle pairing
  // from here on (4 bytes per tetrahedron).
  std::vector<SimplexId> maxima = result.gradient.critical[3];
  std::sort(maxima.begin(), maxima.end(), [&](SimplexId a, SimplexId b) {
    return topo.tetrahedron_input_id(a) < topo.tetrahedron_input_id(b);
  });
  for (size_t i = 0; i < maxima.size(); ++i) up[maxima[i]] = LinkCode::Code(SimplexId(i));
  Pairings().swap(g.down[3]);

  RETURN_IF_ERROR(AppendWalls(structure, g, critical_saddles, input_corners, up, saddles,
                              saddle_tets, context.Slice(0.6, 0.95), result.separatrices));
  // Nothing below reads a relation: the walls' blocks go, and what the phases freed.
  EndPhase(structure);
  std::vector<SimplexId>().swap(saddle_tets);

  Trace::Scope span(context.trace.get(), "segmentations", "phase");
  Segment(topo, g, up, vertex_label, maxima.size(), threads, result);
  if (context.progress) context.progress(1.0);
  return result;
}

#define ACTOPO_INSTANTIATE(S)                                                      \
  template absl::StatusOr<MorseSmaleResult> RunMorseSmale(                         \
      S&, std::span<const SimplexId>, std::span<const uint8_t>, const RunContext&, \
      std::optional<DiscreteGradientResult>);
ACTOPO_FOR_EACH_STRUCTURE(ACTOPO_INSTANTIATE)
#undef ACTOPO_INSTANTIATE

}  // namespace actopo
