#include "server/algorithms/persistence_diagram.h"

#include <algorithm>
#include <numeric>
#include <optional>
#include <queue>
#include <tuple>

#include "absl/container/flat_hash_map.h"
#include "absl/strings/str_cat.h"
#include "server/algorithms/digest.h"
#include "server/algorithms/gradient_paths.h"
#include "server/algorithms/prefetch_off.h"
#include "server/algorithms/union_find.h"
#include "server/core/actopo_structure.h"
#include "server/core/compact_structure.h"
#include "server/core/explicit_structure.h"
#include "server/core/status_macros.h"
#include "server/core/structures.h"

namespace actopo {
namespace {

// A cell's place in the filtration: its vertices' orders, highest first, padded with -1. Cells of
// one dimension compare lexicographically (TTK's simplex comparison), and key[0] is the order of
// the cell's highest vertex.
using FiltrationKey = std::array<SimplexId, 4>;

struct CriticalCell {
  FiltrationKey key;
  SimplexId id;   // internal
  SimplexId top;  // the highest vertex, internal id
  bool operator<(const CriticalCell& o) const { return key < o.key; }
};

CriticalCell MakeCriticalCell(const Topology& topo, std::span<const SimplexId> order, int d,
                              SimplexId c) {
  std::array<SimplexId, 4> v{-1, -1, -1, -1};
  CellVertices(topo, d, c, v.data());
  // Highest order first, by insertion: at most four (std::sort here makes GCC 12 warn about
  // its large-input path, which four elements never take).
  for (int i = 1; i <= d; ++i) {
    for (int j = i; j > 0 && order[v[j]] > order[v[j - 1]]; --j) std::swap(v[j], v[j - 1]);
  }
  CriticalCell cell{{-1, -1, -1, -1}, c, v[0]};
  for (int i = 0; i <= d; ++i) cell.key[i] = order[v[i]];
  return cell;
}

// Union-find over extrema 0..n-1 (positions in the filtration-sorted list) with TTK's rules for
// which extremum dies: `paired` extrema are dead; a component whose root is dead is attached to
// an eternal extremum (the boundary, for maxima).
class Components {
 public:
  explicit Components(size_t n) : sets_(n), paired_(n, false) {}
  int32_t Find(int32_t x) { return sets_.Find(x); }
  // `a`, `b`: roots of two components; `younger_first` orders two live roots. Returns the root
  // that dies (now part of the other component), or -1 when none can (both dead).
  template <class Younger>
  int32_t Merge(int32_t a, int32_t b, Younger younger) {
    if (paired_[a] && paired_[b]) return -1;
    // The dead root survives as the component's root: the merged component is eternal too.
    int32_t dies = paired_[a] ? b : paired_[b] ? a : (younger(a, b) ? a : b);
    const int32_t lives = dies == a ? b : a;
    paired_[dies] = true;
    sets_.Link(dies, lives);
    return dies;
  }
  // The component of root `a` meets the eternal extremum: `a` dies unless already dead.
  bool Kill(int32_t a) {
    if (paired_[a]) return false;
    paired_[a] = true;
    return true;
  }
  bool paired(int32_t x) const { return paired_[x]; }

 private:
  UnionFind sets_;
  std::vector<bool> paired_;
};

// The tetrahedra of triangle f's star, from the star of its lowest vertex (VT, which the
// gradient reads anyway, is far cheaper per block than FT), other than `skip`; at most two.
template <class Reader>
int TriangleTetrahedraBesides(Reader& reader, SimplexId f, SimplexId skip,
                              std::array<SimplexId, 2>& out) {
  const Topology& topo = reader.topology();
  const auto fv = topo.triangle(f);
  int n = 0;
  for (SimplexId t : reader.vertex_star(fv[0])) {
    if (t == skip) continue;
    const auto tv = topo.tetrahedron(t);  // sorted: fv[1] and fv[2] come after fv[0]
    if (std::binary_search(tv.begin(), tv.end(), fv[1]) &&
        std::binary_search(tv.begin(), tv.end(), fv[2])) {
      out[n++] = t;
      if (n == 2) break;
    }
  }
  return n;
}

// A cell that the saddle-max pairing sees when an ascending path leaves through the boundary.
constexpr int32_t kBoundary = -1;

// An edge of a 2-saddle's boundary chain, ordered by its filtration key.
struct ChainEdge {
  uint64_t key;  // order of the higher vertex << 32 | order of the lower one
  SimplexId edge;
  bool operator<(const ChainEdge& o) const { return key < o.key; }
  bool operator==(const ChainEdge& o) const { return edge == o.edge; }
};

// A mod-2 chain of edges as a max-heap where an edge present twice cancels: the youngest edge
// with odd multiplicity is the chain's pivot.
class EdgeChain {
 public:
  void Add(const ChainEdge& e) { heap_.push(e); }
  // Removes and returns the pivot; false when the chain is empty.
  bool PopPivot(ChainEdge& pivot) {
    while (!heap_.empty()) {
      pivot = heap_.top();
      heap_.pop();
      bool odd = true;
      while (!heap_.empty() && heap_.top() == pivot) {
        heap_.pop();
        odd = !odd;
      }
      if (odd) return true;
    }
    return false;
  }
  // The whole chain, youngest edge first, with `first` (a popped pivot) in front; empties it.
  std::vector<ChainEdge> Drain(const ChainEdge& first) {
    std::vector<ChainEdge> out{first};
    ChainEdge e;
    while (PopPivot(e)) out.push_back(e);
    return out;
  }
  void Clear() { heap_ = {}; }

 private:
  std::priority_queue<ChainEdge> heap_;
};

template <TopologicalStructure Structure>
class DiagramBuilder {
 public:
  // `up` and `saddle_tets`: the gradient's AscendingLinks, the 2-saddles' tetrahedra two slots
  // each in ascending saddle id; both empty when it recorded none (crowded triangles).
  DiagramBuilder(Structure& structure, std::span<const SimplexId> order,
                 const DiscreteGradientResult& gradient, std::span<SimplexId> up,
                 std::span<const SimplexId> saddle_tets)
      : structure_(structure),
        topo_(structure.topology()),
        order_(order),
        g_(gradient.gradient),
        critical_(gradient.critical),
        up_(up),
        saddle_tets_(saddle_tets) {}

  absl::Status Run(std::vector<PersistencePair>& pairs, const RunContext& paths_context,
                   const RunContext& reduction_context) {
    CollectCriticalCells();
    RETURN_IF_ERROR(MinSaddlePairs(pairs, paths_context));
    RETURN_IF_ERROR(SaddleMaxPairs(pairs, paths_context));
    RETURN_IF_ERROR(SaddleSaddlePairs(pairs, reduction_context));
    // What never dies: the first minimum of each component, and the 1- and 2-saddles left.
    for (size_t i = 0; i < minima_.size(); ++i) {
      if (!minimum_paired_[i]) pairs.push_back(Infinite(0, minima_[i]));
    }
    for (size_t i = 0; i < saddles1_.size(); ++i) {
      if (!saddle1_paired_[i]) pairs.push_back(Infinite(1, saddles1_[i]));
    }
    for (size_t i = 0; i < saddles2_.size(); ++i) {
      if (!saddle2_paired_[i]) pairs.push_back(Infinite(2, saddles2_[i]));
    }
    return absl::OkStatus();
  }

 private:
  static constexpr const char* kName = "persistence-diagram";

  void CollectCriticalCells() {
    std::array<std::vector<CriticalCell>*, 4> lists = {&minima_, &saddles1_, &saddles2_, &maxima_};
    for (int d = 0; d < 4; ++d) {
      for (SimplexId c : critical_[d]) lists[d]->push_back(MakeCriticalCell(topo_, order_, d, c));
      std::sort(lists[d]->begin(), lists[d]->end());
    }
    for (size_t i = 0; i < minima_.size(); ++i) minimum_index_[minima_[i].id] = int32_t(i);
    for (size_t i = 0; i < maxima_.size(); ++i) maximum_index_[maxima_[i].id] = int32_t(i);
    for (size_t i = 0; i < saddles1_.size(); ++i) saddle1_index_[saddles1_[i].id] = int32_t(i);
    minimum_paired_.assign(minima_.size(), false);
    saddle1_paired_.assign(saddles1_.size(), false);
    saddle2_paired_.assign(saddles2_.size(), false);
    global_max_ = 0;
    for (SimplexId v = 0; v < topo_.num_vertices(); ++v) {
      if (order_[v] > order_[global_max_]) global_max_ = v;
    }
  }

  PersistencePair Finite(int type, const CriticalCell& birth, const CriticalCell& death) const {
    return {int8_t(type), birth.id, death.id, birth.top, death.top};
  }
  PersistencePair Infinite(int type, const CriticalCell& birth) const {
    return {int8_t(type), birth.id, -1, birth.top, global_max_};
  }

  // Each 1-saddle, youngest last, joins the components of the minima its two descending paths
  // reach; the younger root dies with it.
  absl::Status MinSaddlePairs(std::vector<PersistencePair>& pairs, const RunContext& context) {
    std::vector<std::array<int32_t, 2>> ends(saddles1_.size());
    RETURN_IF_ERROR(RunOnConsumersShared(context, int64_t(saddles1_.size()), /*chunk=*/64,
                                         [&](int, ItemQueue& queue, WorkTracker& tracker) {
                                           int64_t begin, end;
                                           while (queue.Next(begin, end)) {
                                             for (int64_t i = begin; i < end; ++i) {
                                               const auto ev = topo_.edge(saddles1_[i].id);
                                               for (int k = 0; k < 2; ++k) {
                                                 ends[i][k] = minimum_index_.at(
                                                     DescendToMinimum(topo_, g_, ev[k]));
                                               }
                                             }
                                             if (!tracker.Done(end - begin)) return;
                                           }
                                         }));
    Components components(minima_.size());
    // Minima are sorted by order: the younger of two has the larger index.
    const auto younger = [](int32_t a, int32_t b) { return a > b; };
    for (size_t i = 0; i < saddles1_.size(); ++i) {
      if (ends[i][0] == ends[i][1]) continue;
      const int32_t a = components.Find(ends[i][0]), b = components.Find(ends[i][1]);
      if (a == b) continue;
      const int32_t dies = components.Merge(a, b, younger);
      if (dies < 0) continue;
      pairs.push_back(Finite(0, minima_[dies], saddles1_[i]));
      minimum_paired_[dies] = true;
      saddle1_paired_[i] = true;
    }
    return absl::OkStatus();
  }

  // Each 2-saddle, youngest first, joins the components of the maxima (or the boundary) its
  // ascending paths reach; the younger root dies with it. TTK's triplets: exactly two distinct
  // ends, else the 2-saddle is left to the saddle-saddle pairing.
  absl::Status SaddleMaxPairs(std::vector<PersistencePair>& pairs, const RunContext& context) {
    std::vector<std::array<int32_t, 2>> ends(saddles2_.size(), {0, 0});
    // The paths are traced in the order of the saddles' ids, which is the order of their blocks:
    // neighbouring saddles climb through the same blocks to the same maxima, so a localized
    // structure reads each block's stars a few times in a row instead of once per saddle met in
    // filtration order.
    std::vector<int32_t> in_space(saddles2_.size());
    std::iota(in_space.begin(), in_space.end(), 0);
    std::sort(in_space.begin(), in_space.end(),
              [&](int32_t a, int32_t b) { return saddles2_[a].id < saddles2_[b].id; });
    // With the gradient's links, each path climbs `up` to a maximum (marked with its index) or
    // off the boundary (-1), and no relation is read; else through triangle stars.
    const bool linked = !up_.empty();
    for (size_t i = 0; linked && i < maxima_.size(); ++i) {
      up_[maxima_[i].id] = LinkCode::Code(SimplexId(i));
    }
    std::optional<PrefetchOff<Structure>> off;
    if (!linked) off.emplace(structure_);
    RETURN_IF_ERROR(RunOnConsumersShared(
        context, int64_t(saddles2_.size()), /*chunk=*/16,
        [&](int, ItemQueue& queue, WorkTracker& tracker) {
          auto reader = structure_.NewReader();
          std::vector<int32_t> reached;
          std::array<SimplexId, 2> star;
          int64_t begin, end;
          while (queue.Next(begin, end)) {
            for (int64_t j = begin; j < end; ++j) {
              const int32_t i = in_space[j];
              const SimplexId f = saddles2_[i].id;
              reached.clear();
              if (linked) {
                const SimplexId* tets = &saddle_tets_[2 * j];  // by id, as in_space
                for (int k = 0; k < 2 && tets[k] >= 0; ++k)
                  reached.push_back(AscendLinked(tets[k]));
              } else {
                const int n = TriangleTetrahedraBesides(reader, f, -1, star);
                for (int k = 0; k < n; ++k) reached.push_back(AscendToMaximum(reader, star[k]));
              }
              ends[i] = SaddleEnds(f, reached);
            }
            if (!tracker.Done(end - begin)) return;
          }
        }));
    off.reset();
    Components components(maxima_.size());
    // Maxima are sorted by filtration order: the younger of two has the smaller index.
    const auto younger = [](int32_t a, int32_t b) { return a < b; };
    for (size_t k = saddles2_.size(); k-- > 0;) {
      if (ends[k][0] == kNoTriplet) continue;
      const int32_t a = components.Find(ends[k][0]);
      int32_t dies = -1;
      if (ends[k][1] == kBoundary) {
        if (components.Kill(a)) dies = a;
      } else {
        const int32_t b = components.Find(ends[k][1]);
        if (a != b) dies = components.Merge(a, b, younger);
      }
      if (dies < 0) continue;
      pairs.push_back(Finite(2, saddles2_[k], maxima_[dies]));
      saddle2_paired_[k] = true;
    }
    return absl::OkStatus();
  }
  static constexpr int32_t kNoTriplet = INT32_MIN;

  // The two ends of 2-saddle f's ascending paths (`reached`, the maxima or kBoundary its
  // tetrahedra climb to), the boundary last; kNoTriplet twice unless exactly two differ.
  std::array<int32_t, 2> SaddleEnds(SimplexId f, std::vector<int32_t>& reached) const {
    if (topo_.triangle_on_boundary(f)) reached.push_back(kBoundary);
    // Maxima ascending, the boundary last.
    std::sort(reached.begin(), reached.end(),
              [](int32_t a, int32_t b) { return (a < 0) != (b < 0) ? b < 0 : a < b; });
    reached.erase(std::unique(reached.begin(), reached.end()), reached.end());
    return reached.size() == 2 ? std::array<int32_t, 2>{reached[0], reached[1]}
                               : std::array<int32_t, 2>{kNoTriplet, kNoTriplet};
  }

  // The maximum (its index) or kBoundary at the end of the ascending path from t, through up_.
  int32_t AscendLinked(SimplexId t) const {
    const SimplexId end = ClimbLinks(up_, t, [](SimplexId, SimplexId) {});
    return end == LinkCode::kBoundary ? kBoundary : int32_t(LinkCode::Label(end));
  }

  // The maximum (its index) at the end of the ascending V-path from tetrahedron t, kBoundary
  // when the path leaves through the boundary.
  template <class Reader>
  int32_t AscendToMaximum(Reader& reader, SimplexId t) const {
    std::array<SimplexId, 2> next;
    while (!g_.IsCritical(3, t)) {
      if (TriangleTetrahedraBesides(reader, g_.down[3][t], t, next) == 0) return kBoundary;
      t = next[0];
    }
    return maximum_index_.at(t);
  }

  ChainEdge EdgeOf(SimplexId e) const {
    const auto ev = topo_.edge(e);
    const SimplexId a = order_[ev[0]], b = order_[ev[1]];
    return {uint64_t(std::max(a, b)) << 32 | uint64_t(std::min(a, b)), e};
  }

  // The 2-saddles left, oldest first, reduce their boundary chains; the pivot of a reduced chain
  // is the 1-saddle it kills. Sequential (one thread): each reduction reads the earlier ones.
  absl::Status SaddleSaddlePairs(std::vector<PersistencePair>& pairs, const RunContext& context) {
    std::vector<size_t> todo;
    for (size_t k = 0; k < saddles2_.size(); ++k) {
      if (!saddle2_paired_[k]) todo.push_back(k);
    }
    // Per 1-saddle (index in saddles1_) paired here: the reduced chain of its 2-saddle.
    absl::flat_hash_map<int32_t, std::vector<ChainEdge>> partner_chain;
    absl::Status error;
    {
      // Reads no relation: triangle edges come from the static encoding.
      RETURN_IF_ERROR(RunOnConsumersShared(
          context, int64_t(todo.size()), /*chunk=*/1,
          [&](int, ItemQueue& queue, WorkTracker& tracker) {
            EdgeChain chain;
            const auto add_triangle = [&](SimplexId f, SimplexId skip) {
              for (SimplexId e : topo_.triangle_edges(f)) {
                if (e != skip) chain.Add(EdgeOf(e));
              }
            };
            int64_t begin, end;
            while (queue.Next(begin, end)) {
              const size_t k = todo[begin];
              chain.Clear();
              add_triangle(saddles2_[k].id, -1);
              ChainEdge pivot;
              while (chain.PopPivot(pivot)) {
                const SimplexId tau = pivot.edge;
                if (const SimplexId f = g_.up[1][tau]; f >= 0) {
                  add_triangle(f, tau);  // tau, a face of f, cancels
                  continue;
                }
                const auto s1 = saddle1_index_.find(tau);
                if (s1 == saddle1_index_.end() || saddle1_paired_[s1->second]) {
                  // Persistence theory rules this out for a valid gradient.
                  error = absl::InternalError(absl::StrCat(kName, ": the boundary of 2-saddle ",
                                                           saddles2_[k].id, " reduced to edge ",
                                                           tau, ", not an unpaired 1-saddle"));
                  return;
                }
                const auto earlier = partner_chain.find(s1->second);
                if (earlier != partner_chain.end()) {
                  const std::vector<ChainEdge>& other = earlier->second;
                  for (size_t i = 1; i < other.size(); ++i) chain.Add(other[i]);  // [0] is tau
                  continue;
                }
                partner_chain.emplace(s1->second, chain.Drain(pivot));
                pairs.push_back(Finite(1, saddles1_[s1->second], saddles2_[k]));
                saddle2_paired_[k] = true;
                break;
              }
              if (!tracker.Done(1)) return;
            }
          }));
    }
    for (const auto& entry : partner_chain) saddle1_paired_[entry.first] = true;
    return error;
  }

  Structure& structure_;
  const Topology& topo_;
  std::span<const SimplexId> order_;
  const GradientField& g_;
  const std::array<std::vector<SimplexId>, 4>& critical_;  // by id
  std::span<SimplexId> up_;                                // AscendingLinks::up, or empty
  std::span<const SimplexId> saddle_tets_;                 // per 2-saddle by id, two slots
  // Critical cells per dimension, in filtration order.
  std::vector<CriticalCell> minima_, saddles1_, saddles2_, maxima_;
  absl::flat_hash_map<SimplexId, int32_t> minimum_index_, maximum_index_, saddle1_index_;
  std::vector<bool> minimum_paired_, saddle1_paired_, saddle2_paired_;
  SimplexId global_max_ = 0;
};

}  // namespace

double PersistenceDiagramResult::MaxPersistence() const {
  double best = 0;
  for (const PersistencePair& p : pairs) best = std::max(best, p.Persistence());
  return best;
}

std::string PersistenceDiagramResult::PairsDigest() const {
  std::vector<std::array<SimplexId, 4>> lines;
  lines.reserve(pairs.size());
  for (const PersistencePair& p : pairs) {
    lines.push_back({p.type, p.birth, p.death, p.finite() ? 1 : 0});
  }
  std::sort(lines.begin(), lines.end());
  StreamedText text;
  for (const auto& l : lines) {
    absl::StrAppend(&text.buffer(), l[0], " ", l[1], " ", l[2], " ", l[3], "\n");
    text.Flush();
  }
  return text.HexDigest();
}

PersistenceCurve ComputePersistenceCurve(const PersistenceDiagramResult& diagram, int type) {
  std::vector<double> values;
  for (const PersistencePair& p : diagram.pairs) {
    if (type < 0 || p.type == type) values.push_back(p.Persistence());
  }
  std::sort(values.begin(), values.end());
  PersistenceCurve curve;
  for (size_t i = 0; i < values.size(); ++i) {
    if (i > 0 && values[i] == values[i - 1]) continue;
    curve.persistence.push_back(values[i]);
    curve.pairs.push_back(int32_t(values.size() - i));
  }
  return curve;
}

RelationSet PersistenceDiagramDeclared() { return {Relation::kVE, Relation::kVF, Relation::kVT}; }

template <TopologicalStructure Structure>
absl::StatusOr<PersistenceDiagramResult> RunPersistenceDiagram(
    Structure& structure, std::span<const SimplexId> order, std::span<const double> scalars,
    const RunContext& context, VertexNeighbors* neighbors, GradientArrays arrays) {
  const Topology& topo = structure.topology();
  if (scalars.size() != size_t(topo.num_vertices()) || order.size() != scalars.size()) {
    return absl::InvalidArgumentError(
        absl::StrCat("persistence-diagram: ", scalars.size(), " scalars and ", order.size(),
                     " vertex orders for ", topo.num_vertices(), " vertices"));
  }
  // Progress: the gradient 60%, the paths 25%, the saddle-saddle reduction the rest.
  const auto phase = [&context](double from, double to, int consumers) {
    RunContext part = context.Slice(from, to);
    part.consumers = consumers;
    return part;
  };
  PersistenceDiagramResult result;
  // The ascending paths follow the links the gradient's sweep records (4 bytes per tetrahedron,
  // as many as the tetrahedron -> triangle pairs they replace): following triangle stars instead
  // would compute blocks' VT again after the sweep, on compact and actopo.
  const bool linked = !topo.has_crowded_triangles();
  std::vector<SimplexId> up, saddle_tets;
  AscendingLinks links;
  if (linked) {
    up.assign(size_t(topo.num_tetrahedra()), -1);
    links.up = up;
    links.saddles.resize(size_t(std::max(context.consumers, 1)));
  }
  {
    auto gradient = RunDiscreteGradient(structure, order, phase(0.0, 0.6, context.consumers),
                                        linked ? arrays : GradientArrays::kPersistence, neighbors,
                                        linked ? &links : nullptr);
    if (!gradient.ok()) return gradient.status();
    result.gradient = std::move(*gradient);
  }
  if (linked) {
    ASSIGN_OR_RETURN(saddle_tets, SaddleTetrahedra(links, result.gradient.critical[2]));
  }
  std::vector<PersistencePair>& pairs = result.pairs;
  {
    Trace::Scope span(context.trace.get(), "pairs", "phase");
    DiagramBuilder<Structure> builder(structure, order, result.gradient, up, saddle_tets);
    RETURN_IF_ERROR(builder.Run(pairs, phase(0.6, 0.85, context.consumers), phase(0.85, 1.0, 1)));
  }
  for (PersistencePair& p : pairs) {
    p.birth = topo.vertex_input_id(p.birth);
    p.death = topo.vertex_input_id(p.death);
    p.birth_value = scalars[p.birth];
    p.death_value = scalars[p.death];
    (p.finite() ? result.finite : result.infinite)[p.type]++;
  }
  // TTK sorts by the birth vertex's order; its sort is not stable, ours breaks ties by type,
  // then death order.
  const auto input_order = [&](SimplexId input) { return order[topo.vertex_internal_id(input)]; };
  std::sort(pairs.begin(), pairs.end(), [&](const PersistencePair& a, const PersistencePair& b) {
    return std::make_tuple(input_order(a.birth), a.type, input_order(a.death)) <
           std::make_tuple(input_order(b.birth), b.type, input_order(b.death));
  });
  if (context.progress) context.progress(1.0);
  return result;
}

#define ACTOPO_INSTANTIATE(S)                                                     \
  template absl::StatusOr<PersistenceDiagramResult> RunPersistenceDiagram(        \
      S&, std::span<const SimplexId>, std::span<const double>, const RunContext&, \
      VertexNeighbors*, GradientArrays);
ACTOPO_FOR_EACH_STRUCTURE(ACTOPO_INSTANTIATE)
#undef ACTOPO_INSTANTIATE

}  // namespace actopo
