#include "server/algorithms/morse_smale.h"

#include <algorithm>
#include <map>
#include <queue>

#include "absl/strings/str_cat.h"
#include "server/algorithms/digest.h"
#include "server/core/actopo_structure.h"
#include "server/core/compact_structure.h"
#include "server/core/explicit_structure.h"

namespace actopo {
namespace {

// Everything after the gradient, on one reader.
template <class Reader>
class Builder {
 public:
  Builder(Reader& reader, const GradientField& gradient,
          std::span<const SimplexId> input_tetrahedra, const RunContext& context)
      : r_(reader),
        topo_(reader.topology()),
        g_(gradient),
        input_tets_(input_tetrahedra),
        context_(context) {}

  bool cancelled() const {
    return context_.cancel != nullptr && context_.cancel->load(std::memory_order_relaxed);
  }

  void DescendingSeparatrices(std::vector<Separatrix>& out) {
    for (SimplexId e = 0; e < topo_.num_edges(); ++e) {
      if (!g_.IsCritical(1, e)) continue;
      for (SimplexId start : topo_.edge(e)) {
        Separatrix s{SeparatrixType::kDescending, {1, e}, {}, {{1, e}}};
        SimplexId v = start;
        while (true) {
          s.cells.push_back({0, v});
          if (g_.IsCritical(0, v)) break;
          const SimplexId edge = g_.up[0][v];
          s.cells.push_back({1, edge});
          const auto ev = topo_.edge(edge);
          v = ev[0] == v ? ev[1] : ev[0];
        }
        s.destination = s.cells.back();
        out.push_back(std::move(s));
      }
    }
  }

  void AscendingSeparatrices(std::vector<Separatrix>& out) {
    for (SimplexId f = 0; f < topo_.num_triangles(); ++f) {
      if (!g_.IsCritical(2, f)) continue;
      const auto star = r_.triangle_star(f);
      star_.assign(star.begin(), star.end());
      SortByInputId(star_);  // TTK's order of the saddle's star
      for (SimplexId t : star_) {
        Separatrix s{SeparatrixType::kAscending, {2, f}, {}, {{2, f}}};
        if (AscendingPath(t, s.cells)) {
          s.destination = s.cells.back();
          out.push_back(std::move(s));
        }
      }
    }
  }

  // Saddle connectors: for each 2-saddle, its descending wall (triangles reached through the
  // up-pairs of their edges) and, from each 1-saddle on it, the path up through the wall.
  void SaddleConnectors(std::vector<Separatrix>& out) {
    visited_.assign(topo_.num_triangles(), 0);
    for (SimplexId s2 = 0; s2 < topo_.num_triangles(); ++s2) {
      if (!g_.IsCritical(2, s2)) continue;
      if (cancelled()) return;
      DescendingWall(s2);
      for (SimplexId s1 : wall_saddles_) {
        Separatrix s{SeparatrixType::kSaddleConnector, {1, s1}, {2, s2}, {}};
        if (PathThroughWall(s1, s.cells) && s.cells.back().dim == 2 && s.cells.back().id == s2) {
          out.push_back(std::move(s));
        }
      }
      for (SimplexId f : wall_) visited_[f] = 0;
    }
  }

  // Minima labelled 0.. in ascending vertex id; each vertex takes its V-path's minimum.
  std::vector<SimplexId> DescendingSegmentation(std::vector<int64_t>& sizes) {
    const SimplexId nv = topo_.num_vertices();
    std::vector<SimplexId> minima;
    for (SimplexId v = 0; v < nv; ++v) {
      if (g_.IsCritical(0, v)) minima.push_back(v);
    }
    SortVerticesByInputId(minima);
    std::vector<SimplexId> label(nv, -1);  // internal ids
    if (minima.size() == 1) {
      std::fill(label.begin(), label.end(), 0);  // as TTK: every vertex, used or not
    } else {
      for (size_t i = 0; i < minima.size(); ++i) label[minima[i]] = SimplexId(i);
      std::vector<SimplexId> path;
      for (SimplexId v = 0; v < nv; ++v) {
        SimplexId cur = v;
        path.clear();
        while (label[cur] == -1) {
          path.push_back(cur);
          const auto ev = topo_.edge(g_.up[0][cur]);
          cur = ev[0] == cur ? ev[1] : ev[0];
        }
        for (SimplexId p : path) label[p] = label[cur];
      }
    }
    sizes.assign(minima.size(), 0);
    for (SimplexId l : label) {
      if (l >= 0) ++sizes[l];
    }
    return ToInputOrder(label);
  }

  // Maxima (critical tetrahedra) labelled 0.. in ascending tetrahedron id; each tetrahedron
  // follows its path up, -1 if it leaves through the boundary; a vertex takes the label of the
  // lowest-id tetrahedron of its star.
  std::vector<SimplexId> AscendingSegmentation(std::vector<int64_t>& sizes) {
    const SimplexId nt = topo_.num_tetrahedra();
    std::vector<SimplexId> maxima;
    for (SimplexId t = 0; t < nt; ++t) {
      if (g_.IsCritical(3, t)) maxima.push_back(t);
    }
    std::sort(maxima.begin(), maxima.end(), [&](SimplexId a, SimplexId b) {
      return topo_.tetrahedron_input_id(a) < topo_.tetrahedron_input_id(b);
    });
    const SimplexId nv = topo_.num_vertices();
    std::vector<SimplexId> vertex_label(nv, -1);
    sizes.assign(maxima.size(), 0);
    if (!maxima.empty()) {
      std::vector<SimplexId> label(nt, -1);
      std::vector<uint8_t> done(nt, 0);
      for (size_t i = 0; i < maxima.size(); ++i) {
        label[maxima[i]] = SimplexId(i);
        done[maxima[i]] = 1;
      }
      std::vector<SimplexId> path;
      for (SimplexId t = 0; t < nt; ++t) {
        if (done[t]) continue;
        path.clear();
        SimplexId cur = t;
        while (!done[cur]) {
          path.push_back(cur);
          const SimplexId next = FirstOtherTet(g_.down[3][cur], cur);
          if (next == cur) break;  // left through the boundary
          cur = next;
        }
        const SimplexId l = done[cur] ? label[cur] : -1;
        for (SimplexId p : path) {
          label[p] = l;
          done[p] = 1;
        }
        if ((t & 1023) == 0 && cancelled()) return {};
      }
      for (SimplexId v = 0; v < nv; ++v) {
        const auto star = r_.vertex_star(v);
        if (star.empty()) continue;
        SimplexId first = star[0];
        for (SimplexId t : star) {
          if (topo_.tetrahedron_input_id(t) < topo_.tetrahedron_input_id(first)) first = t;
        }
        vertex_label[v] = label[first];
      }
      for (SimplexId l : vertex_label) {
        if (l >= 0) ++sizes[l];
      }
    }
    return ToInputOrder(vertex_label);
  }

 private:
  // tet -> its paired triangle -> the next tetrahedron ... until a critical tetrahedron. False
  // when the path ends elsewhere (through the boundary or at a critical triangle).
  bool AscendingPath(SimplexId tet, std::vector<Cell>& cells) {
    SimplexId cur = tet;
    while (true) {
      cells.push_back({3, cur});
      if (g_.IsCritical(3, cur)) return true;
      const SimplexId f = g_.down[3][cur];
      cells.push_back({2, f});
      if (g_.IsCritical(2, f)) return false;
      const SimplexId next = FirstOtherTet(f, cur);
      if (next == cur) return false;
      cur = next;
    }
  }

  // The first tetrahedron of f's star, in TTK's order (ascending input id), other than `cur`;
  // `cur` itself when there is none.
  SimplexId FirstOtherTet(SimplexId f, SimplexId cur) {
    SimplexId best = cur;
    for (SimplexId t : r_.triangle_star(f)) {
      if (t == cur) continue;
      if (best == cur || topo_.tetrahedron_input_id(t) < topo_.tetrahedron_input_id(best)) {
        best = t;
      }
    }
    return best;
  }

  void DescendingWall(SimplexId s2) {
    wall_.clear();
    wall_saddles_.clear();
    std::queue<SimplexId> bfs;
    bfs.push(s2);
    while (!bfs.empty()) {
      const SimplexId f = bfs.front();
      bfs.pop();
      if (visited_[f]) continue;
      visited_[f] = 1;
      wall_.push_back(f);
      for (SimplexId e : r_.triangle_edges(f)) {
        if (g_.IsCritical(1, e)) wall_saddles_.push_back(e);
        const SimplexId paired = g_.up[1][e];
        if (paired >= 0 && paired != f) bfs.push(paired);
      }
    }
    std::sort(wall_saddles_.begin(), wall_saddles_.end());
    wall_saddles_.erase(std::unique(wall_saddles_.begin(), wall_saddles_.end()),
                        wall_saddles_.end());
  }

  // From 1-saddle s1 up through the current wall: triangle -> its paired edge -> the wall
  // triangle around that edge other than the previous one (the last in TTK's edge-triangle
  // order when several) ... until a critical cell or a dead end. False if s1 touches no wall
  // triangle.
  bool PathThroughWall(SimplexId s1, std::vector<Cell>& cells) {
    cells.push_back({1, s1});
    SimplexId cur = -1;
    candidates_.clear();
    for (SimplexId f : r_.edge_triangles(s1)) {
      if (!visited_[f]) continue;
      if (g_.IsCritical(2, f)) {
        cells.push_back({2, f});
        return true;
      }
      candidates_.push_back(f);
    }
    if (candidates_.empty()) return false;
    cur = LastInTtkOrder(candidates_);
    // A valid gradient has no cycle here; the bound only guards against looping forever.
    for (size_t steps = 0; steps <= wall_.size(); ++steps) {
      const SimplexId old = cur;
      cells.push_back({2, cur});
      if (g_.IsCritical(2, cur)) return true;
      const SimplexId e = g_.down[2][cur];
      cells.push_back({1, e});
      if (g_.IsCritical(1, e)) return true;
      candidates_.clear();
      for (SimplexId f : r_.edge_triangles(e)) {
        if (visited_[f] && f != old) candidates_.push_back(f);
      }
      if (candidates_.empty()) return true;  // dead end: the path stops at edge e
      cur = LastInTtkOrder(candidates_);
    }
    return true;
  }

  // TTK numbers triangles by first appearance over tetrahedra in input order, faces (v0 v1 v2),
  // (v1 v2 v3), (v2 v3 v0), (v3 v0 v1) of the tetrahedron as given.
  uint64_t TtkTriangleRank(SimplexId f) {
    const auto fv = topo_.triangle(f);
    uint64_t best = UINT64_MAX;
    for (SimplexId t : r_.triangle_star(f)) {
      const SimplexId input = topo_.tetrahedron_input_id(t);
      const SimplexId* tv = &input_tets_[4 * size_t(input)];
      int omitted = 0;
      for (int p = 0; p < 4; ++p) {
        const SimplexId v = topo_.vertex_internal_id(tv[p]);
        if (v != fv[0] && v != fv[1] && v != fv[2]) omitted = p;
      }
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

  void SortByInputId(std::vector<SimplexId>& tets) const {
    std::sort(tets.begin(), tets.end(), [&](SimplexId a, SimplexId b) {
      return topo_.tetrahedron_input_id(a) < topo_.tetrahedron_input_id(b);
    });
  }
  void SortVerticesByInputId(std::vector<SimplexId>& vertices) const {
    std::sort(vertices.begin(), vertices.end(), [&](SimplexId a, SimplexId b) {
      return topo_.vertex_input_id(a) < topo_.vertex_input_id(b);
    });
  }
  std::vector<SimplexId> ToInputOrder(const std::vector<SimplexId>& by_internal) const {
    std::vector<SimplexId> out(by_internal.size());
    for (SimplexId v = 0; v < SimplexId(by_internal.size()); ++v) {
      out[topo_.vertex_input_id(v)] = by_internal[v];
    }
    return out;
  }

  Reader& r_;
  const Topology& topo_;
  const GradientField& g_;
  std::span<const SimplexId> input_tets_;
  const RunContext& context_;
  std::vector<uint8_t> visited_;
  std::vector<SimplexId> wall_, wall_saddles_, candidates_, star_;
};

std::vector<SimplexId> FinalSegmentation(const std::vector<SimplexId>& descending,
                                         const std::vector<SimplexId>& ascending,
                                         int64_t num_maxima) {
  std::vector<int64_t> sparse(descending.size());
  for (size_t v = 0; v < sparse.size(); ++v) {
    sparse[v] = descending[v] < 0 || ascending[v] < 0
                    ? -1
                    : int64_t(descending[v]) * num_maxima + ascending[v];
  }
  // Dense ranks of the distinct sparse ids, -1 included (so it becomes region 0, as in TTK).
  std::vector<int64_t> distinct = sparse;
  std::sort(distinct.begin(), distinct.end());
  distinct.erase(std::unique(distinct.begin(), distinct.end()), distinct.end());
  std::vector<SimplexId> out(sparse.size());
  for (size_t v = 0; v < sparse.size(); ++v) {
    out[v] = SimplexId(std::lower_bound(distinct.begin(), distinct.end(), sparse[v]) -
                       distinct.begin());
  }
  return out;
}

}  // namespace

int64_t MorseSmaleResult::CountSeparatrices(SeparatrixType type) const {
  return std::count_if(separatrices.begin(), separatrices.end(),
                       [&](const Separatrix& s) { return s.type == type; });
}

int64_t MorseSmaleResult::Segments() const {
  int64_t n = 0;
  for (const Separatrix& s : separatrices) n += int64_t(s.cells.size()) - 1;
  return n;
}

int64_t MorseSmaleResult::Regions(std::span<const SimplexId> labels) {
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
  return {Relation::kVE, Relation::kVF, Relation::kVT,
          Relation::kFT, Relation::kFE, Relation::kEF};
}

template <class Structure>
absl::StatusOr<MorseSmaleResult> RunMorseSmale(Structure& structure,
                                               std::span<const SimplexId> order,
                                               std::span<const SimplexId> input_tetrahedra,
                                               const RunContext& context) {
  const Topology& topo = structure.topology();
  if (input_tetrahedra.size() != 4 * size_t(topo.num_tetrahedra())) {
    return absl::InvalidArgumentError(absl::StrCat(
        "morse-smale: ", input_tetrahedra.size(), " tetrahedron vertex ids for ",
        topo.num_tetrahedra(), " tetrahedra"));
  }
  // Progress: the gradient is the first half, the rest the second.
  auto report = [&](double f) {
    if (context.progress) context.progress(f);
  };
  RunContext gradient_context = context;
  if (context.progress) gradient_context.progress = [&](double f) { report(0.5 * f); };
  MorseSmaleResult result;
  {
    auto gradient = RunDiscreteGradient(structure, order, gradient_context);
    if (!gradient.ok()) return gradient.status();
    result.gradient = std::move(*gradient);
  }
  auto reader = structure.NewReader();
  Builder builder(reader, result.gradient.gradient, input_tetrahedra, context);
  const auto cancelled = [&] { return absl::CancelledError("the run was cancelled"); };

  builder.DescendingSeparatrices(result.separatrices);
  report(0.55);
  builder.AscendingSeparatrices(result.separatrices);
  report(0.6);
  if (builder.cancelled()) return cancelled();
  builder.SaddleConnectors(result.separatrices);
  report(0.8);
  if (builder.cancelled()) return cancelled();
  result.descending = builder.DescendingSegmentation(result.minimum_sizes);
  result.ascending = builder.AscendingSegmentation(result.maximum_sizes);
  if (builder.cancelled()) return cancelled();
  result.morse_smale = FinalSegmentation(result.descending, result.ascending,
                                         int64_t(result.maximum_sizes.size()));
  report(1.0);
  return result;
}

template absl::StatusOr<MorseSmaleResult> RunMorseSmale(ExplicitStructure&,
                                                        std::span<const SimplexId>,
                                                        std::span<const SimplexId>,
                                                        const RunContext&);
template absl::StatusOr<MorseSmaleResult> RunMorseSmale(CompactStructure&,
                                                        std::span<const SimplexId>,
                                                        std::span<const SimplexId>,
                                                        const RunContext&);
template absl::StatusOr<MorseSmaleResult> RunMorseSmale(ActopoStructure&,
                                                        std::span<const SimplexId>,
                                                        std::span<const SimplexId>,
                                                        const RunContext&);

}  // namespace actopo
