#include "server/algorithms/topological_simplification.h"

#include <sys/mman.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <functional>
#include <limits>
#include <new>
#include <optional>
#include <queue>
#include <tuple>
#include <type_traits>
#include <utility>

#include "absl/strings/str_cat.h"
#include "server/algorithms/digest.h"
#include "server/algorithms/prefetch_off.h"
#include "server/algorithms/union_find.h"
#include "server/algorithms/vertex_neighbors.h"
#include "server/core/actopo_structure.h"
#include "server/core/compact_structure.h"
#include "server/core/explicit_structure.h"
#include "server/core/status_macros.h"
#include "server/core/structures.h"

namespace actopo {
namespace {

constexpr const char* kName = "topological-simplification";

// Whether v, of neighbours `neighbors`, is a local minimum (bit 0) or maximum (bit 1) of
// `order`: no lower, no higher neighbour.
constexpr uint8_t kMinimum = 1, kMaximum = 2;
uint8_t ExtremumFlags(std::span<const SimplexId> neighbors, SimplexId v,
                      std::span<const SimplexId> order) {
  bool lower = false, higher = false;
  for (SimplexId u : neighbors) (order[u] < order[v] ? lower : higher) = true;
  return (lower ? 0 : kMinimum) | (higher ? 0 : kMaximum);
}

// What the removal passes read: every vertex's neighbours (VV). The passes go back over the same
// components (growth, segment, local orders, flags) in the order of their extrema, which is no
// order in space: through a localized structure, one consumer would compute most blocks' VV
// again and again while its leader prefetched blocks in id order. On compact and actopo the rows
// are therefore those the diagram's gradient kept while it held each block's VE (VertexNeighbors:
// 2 bytes per near neighbour, 4 per vertex); the explicit structure's own rows are read in place.
template <TopologicalStructure Structure>
class NeighborRows {
 public:
  static constexpr bool kInPlace = Structure::kRelationsInPlace;

  // `kept`: filled for every block, unless kInPlace (then unused, may be null). As a reader's,
  // a row is valid until the next vertex_neighbors call.
  NeighborRows(Structure& structure, const VertexNeighbors* kept)
      : topo_(&structure.topology()), kept_(kept) {
    if constexpr (kInPlace) reader_.emplace(structure.NewReader());
  }

  const Topology& topology() const { return *topo_; }

  std::span<const SimplexId> vertex_neighbors(SimplexId v) {
    if constexpr (kInPlace) {
      return reader_->vertex_neighbors(v);
    } else {
      return kept_->vertex_neighbors(v, row_);
    }
  }

 private:
  using Reader = decltype(std::declval<Structure&>().NewReader());

  const Topology* topo_;
  const VertexNeighbors* kept_;
  std::vector<SimplexId> row_;    // the last row decoded from kept_
  std::optional<Reader> reader_;  // explicit: read in place
};

// Per vertex, a value that is -1 until set, in memory of which only the pages written become
// resident: anonymous zero pages, a value x stored as x + 1 (reading an unwritten page maps the
// shared zero page). A removal pass reaches a few percent of the vertices, and its four arrays
// over all of them, filled with -1, would add to the simplified complex's peak.
class SparseVertexValues {
 public:
  class Ref {
   public:
    explicit Ref(uint32_t* p) : p_(p) {}
    operator SimplexId() const { return SimplexId(*p_ - 1u); }
    Ref& operator=(SimplexId x) {
      *p_ = uint32_t(x) + 1u;
      return *this;
    }
    Ref& operator=(const Ref& other) { return *this = SimplexId(other); }
    Ref& operator-=(SimplexId x) { return *this = SimplexId(*this) - x; }

   private:
    uint32_t* p_;
  };

  SparseVertexValues() = default;
  ~SparseVertexValues() { Free(); }
  SparseVertexValues(const SparseVertexValues&) = delete;
  SparseVertexValues& operator=(const SparseVertexValues&) = delete;

  // n values, all -1.
  void Reset(SimplexId n) {
    Free();
    bytes_ = std::max<size_t>(size_t(n), 1) * sizeof(uint32_t);
    void* p = ::mmap(nullptr, bytes_, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
    if (p == MAP_FAILED) throw std::bad_alloc();
    data_ = static_cast<uint32_t*>(p);
  }
  Ref operator[](SimplexId v) { return Ref(data_ + v); }

 private:
  void Free() {
    if (data_ != nullptr) ::munmap(data_, bytes_);
    data_ = nullptr;
  }
  uint32_t* data_ = nullptr;
  size_t bytes_ = 0;
};

// A superlevel-set component growing from one maximum (LTS's "propagation"): a max-heap of
// (order, vertex) on its frontier; merged components share the heap of the dominant one.
struct Propagation {
  int32_t parent;                   // the component it was merged into (itself while it grows)
  std::vector<SimplexId> critical;  // [0] the maximum, then the saddles it met
  std::priority_queue<std::pair<SimplexId, SimplexId>> queue;
  int64_t segment_size = 0;
  std::vector<SimplexId> segment;
};

// Removes the maxima that are not `authorized` from `order` (internal ids, ranks 0..n-1),
// LTS's detectAndRemoveUnauthorizedMaxima; returns the components that were flattened.
template <class Reader>
class MaximaRemoval {
 public:
  // `maxima`: the local maxima of `order` that are not authorized.
  MaximaRemoval(Reader& reader, std::vector<SimplexId>& order, std::vector<SimplexId> maxima)
      : r_(reader),
        topo_(reader.topology()),
        order_(order),
        n_(topo_.num_vertices()),
        maxima_(std::move(maxima)) {}

  absl::Status Run() {
    segmentation_.Reset(n_);
    queue_mask_.Reset(n_);
    local_order_.Reset(n_);
    owner_.Reset(n_);
    InitializePropagations();
    for (size_t p = 0; p < props_.size(); ++p) RETURN_IF_ERROR(Propagate(int32_t(p)));
    for (size_t p = 0; p < props_.size(); ++p) {
      if (props_[p].parent == int32_t(p)) parents_.push_back(int32_t(p));
    }
    for (int32_t p : parents_) RETURN_IF_ERROR(ComputeSegment(props_[p]));
    for (int32_t p : parents_) RETURN_IF_ERROR(ComputeLocalOrder(props_[p]));
    for (int32_t p : parents_) {
      local_order_[props_[p].critical.back()] = std::numeric_limits<SimplexId>::max();
    }
    // Vertices by rank before flattening: the ones left alone keep their relative order.
    std::vector<SimplexId> by_rank(n_);
    for (SimplexId v = 0; v < n_; ++v) by_rank[order_[v]] = v;
    for (int32_t p : parents_) {  // flatten the order to the saddle's
      const SimplexId saddle_order = order_[props_[p].critical.back()];
      for (SimplexId v : props_[p].segment) order_[v] = saddle_order;
    }
    GlobalOrder(by_rank);
    return absl::OkStatus();
  }

  // The flattened components: their vertices take the value of their saddle.
  std::vector<std::pair<SimplexId, std::vector<SimplexId>>> TakeSegments() {
    std::vector<std::pair<SimplexId, std::vector<SimplexId>>> out;
    for (int32_t p : parents_) {
      out.emplace_back(props_[p].critical.back(), std::move(props_[p].segment));
    }
    return out;
  }
  int64_t removed() const { return int64_t(props_.size()); }

 private:
  // A propagation per maximum to remove, ascending order. (With no constraint at all TTK keeps
  // the highest maximum; the caller does not simplify then.)
  void InitializePropagations() {
    std::vector<SimplexId>& maxima = maxima_;
    std::sort(maxima.begin(), maxima.end(),
              [&](SimplexId a, SimplexId b) { return order_[a] < order_[b]; });
    props_.resize(maxima.size());
    components_.Reset(maxima.size());
    for (size_t p = 0; p < maxima.size(); ++p) {
      props_[p].parent = int32_t(p);
      props_[p].critical = {maxima[p]};
    }
  }

  int32_t Find(int32_t p) { return components_.Find(p); }

  void Unify(int32_t into, int32_t other) {
    if (other < 0) return;
    into = Find(into);
    other = Find(other);
    if (into == other) return;
    Propagation& a = props_[into];
    Propagation& b = props_[other];
    b.parent = into;
    components_.Link(other, into);
    a.segment_size += b.segment_size;
    if (a.queue.size() < b.queue.size()) std::swap(a.queue, b.queue);
    while (!b.queue.empty()) {
      a.queue.push(b.queue.top());
      b.queue.pop();
    }
  }

  // Grows propagation p from its maximum, highest frontier vertex first, until a saddle: a
  // vertex with a larger neighbour outside the component. There it stops unless every larger
  // neighbour has been reached by some component, in which case the components around the saddle
  // merge into the one of the highest maximum, which goes on.
  absl::Status Propagate(int32_t p) {
    int32_t current = p;
    SimplexId segment_id = props_[current].critical[0];
    props_[current].queue.emplace(order_[segment_id], segment_id);
    queue_mask_[segment_id] = segment_id;
    while (!props_[current].queue.empty()) {
      const SimplexId v = props_[current].queue.top().second;
      props_[current].queue.pop();
      if (owner_[v] >= 0) continue;
      bool saddle = false;
      SimplexId larger = 0, larger_here = 0;
      for (SimplexId u : r_.vertex_neighbors(v)) {
        if (order_[u] > order_[v]) {
          ++larger;
          if (owner_[u] < 0 || Find(owner_[u]) != current) {
            saddle = true;
          } else {
            ++larger_here;
          }
        } else if (queue_mask_[u] != segment_id) {
          props_[current].queue.emplace(order_[u], u);
          queue_mask_[u] = segment_id;
        }
      }
      if (saddle) {
        props_[current].critical.push_back(v);
        segmentation_[v] -= larger_here;  // counts the larger neighbours reached so far
        if (segmentation_[v] != -larger - 1) return absl::OkStatus();
        neighbors_.clear();
        for (SimplexId u : r_.vertex_neighbors(v)) {
          if (owner_[u] < 0) continue;
          const int32_t root = Find(owner_[u]);
          neighbors_.push_back(root);
          if (order_[props_[root].critical[0]] > order_[props_[current].critical[0]]) {
            current = root;
          }
        }
        for (int32_t other : neighbors_) Unify(current, other);
        segment_id = props_[current].critical[0];
      }
      owner_[v] = current;
      segmentation_[v] = segment_id;
      ++props_[current].segment_size;
    }
    return absl::FailedPreconditionError(absl::StrCat(
        kName, ": the component of maximum ", topo_.vertex_input_id(props_[p].critical[0]),
        " grew over the whole mesh: the constraints must keep a global extremum"));
  }

  // The component's vertices: those reached above its saddle, connected to its maximum.
  absl::Status ComputeSegment(Propagation& prop) {
    const SimplexId extremum = prop.critical[0];
    const SimplexId saddle_order = order_[prop.critical.back()];
    prop.segment.clear();
    if (prop.segment_size > 0) {
      std::vector<SimplexId> stack{extremum};
      segmentation_[extremum] = kVisited;
      while (!stack.empty()) {
        const SimplexId v = stack.back();
        stack.pop_back();
        prop.segment.push_back(v);
        for (SimplexId u : r_.vertex_neighbors(v)) {
          if (segmentation_[u] >= 0 && order_[u] > saddle_order) {
            segmentation_[u] = kVisited;
            stack.push_back(u);
          }
        }
      }
    }
    if (int64_t(prop.segment.size()) != prop.segment_size) {
      return absl::InternalError(
          absl::StrCat(kName, ": the component of maximum ", topo_.vertex_input_id(extremum),
                       " has ", prop.segment.size(), " vertices, expected ", prop.segment_size));
    }
    for (SimplexId v : prop.segment) segmentation_[v] = extremum;
    return absl::OkStatus();
  }

  // An order of the component's vertices without extrema inside it: alternately by superlevel
  // sets from the saddle and by sublevel sets from the component's boundary, until neither leaves
  // a maximum nor a minimum (LTS's computeLocalOrderOfSegment).
  absl::Status ComputeLocalOrder(Propagation& prop) {
    if (prop.segment_size == 1) {
      local_order_[prop.segment[0]] = -2;
      return absl::OkStatus();
    }
    for (SimplexId v : prop.segment) local_order_[v] = order_[v] - n_;
    const SimplexId extremum = prop.critical[0];
    const SimplexId saddle = prop.critical.back();
    std::vector<SimplexId> boundary, sequence(prop.segment.size() + 1);
    bool superlevel = true;
    // TTK warns after 20 iterations and has no bound; a bound keeps a server thread from spinning.
    for (int iteration = 0; iteration < kMaxLocalOrderIterations; ++iteration) {
      LocalOrderIteration(prop, superlevel, boundary, sequence, extremum, saddle);
      superlevel = !superlevel;
      size_t on_boundary = 0;
      int64_t residual = 0;
      for (SimplexId v : prop.segment) {
        bool outside = false, smaller = false, greater = false;
        const SimplexId mine = local_order_[v];
        for (SimplexId u : r_.vertex_neighbors(v)) {
          if (u == saddle) {
            greater = true;
          } else if (segmentation_[u] != extremum) {
            outside = true;
          } else if (local_order_[u] > mine) {
            greater = true;
          } else {
            smaller = true;
          }
        }
        residual += !greater;
        if (outside) {
          sequence[on_boundary++] = v;
        } else if (!smaller) {
          ++residual;
        }
      }
      if (residual == 0) return absl::OkStatus();
      if (boundary.empty()) boundary.assign(sequence.begin(), sequence.begin() + on_boundary);
    }
    return absl::InternalError(
        absl::StrCat(kName, ": the component of maximum ", topo_.vertex_input_id(extremum),
                     " keeps extrema after ", kMaxLocalOrderIterations, " reorderings"));
  }

  void LocalOrderIteration(const Propagation& prop, bool superlevel,
                           const std::vector<SimplexId>& boundary, std::vector<SimplexId>& sequence,
                           SimplexId extremum, SimplexId saddle) {
    const SimplexId size = SimplexId(prop.segment.size());
    std::priority_queue<std::pair<SimplexId, SimplexId>> queue;
    if (superlevel) {
      queue.emplace(std::numeric_limits<SimplexId>::max(), saddle);
    } else {
      const SimplexId offset = -size - 1;  // keeps the inverted orders negative
      for (SimplexId v : prop.segment) local_order_[v] = offset - local_order_[v];
      for (SimplexId v : boundary) {
        queue.emplace(local_order_[v], v);
        local_order_[v] = 0;
      }
      queue.emplace(std::numeric_limits<SimplexId>::min(), saddle);
    }
    size_t q = 0;
    while (!queue.empty()) {
      const SimplexId v = queue.top().second;
      queue.pop();
      sequence[q++] = v;
      for (SimplexId u : r_.vertex_neighbors(v)) {
        if (segmentation_[u] == extremum && local_order_[u] < 0) {
          queue.emplace(local_order_[u], u);
          local_order_[u] = 0;
        }
      }
    }
    if (superlevel) {
      for (SimplexId i = 1; i <= size; ++i) local_order_[sequence[i]] = -i;
    } else {
      for (SimplexId i = 0; i < size; ++i) local_order_[sequence[i]] = i - size;
    }
  }

  // Ranks of (order, local order, input id): flattened components sit just below their saddle.
  // TTK sorts every vertex by that key; the vertices left alone are already in order
  // (`by_rank`, their orders unique), so only the flattened ones are sorted, then merged in.
  void GlobalOrder(const std::vector<SimplexId>& by_rank) {
    using Key = std::tuple<SimplexId, SimplexId, SimplexId, SimplexId>;
    const auto key = [&](SimplexId v) -> Key {
      return {order_[v], local_order_[v], topo_.vertex_input_id(v), v};
    };
    std::vector<bool> flattened(n_, false);
    std::vector<Key> moved;
    for (int32_t p : parents_) {
      for (SimplexId v : props_[p].segment) {
        flattened[v] = true;
        moved.push_back(key(v));
      }
    }
    std::sort(moved.begin(), moved.end());
    SimplexId rank = 0;
    size_t next = 0;
    for (SimplexId v : by_rank) {
      if (flattened[v]) continue;
      const Key k = key(v);
      for (; next < moved.size() && moved[next] < k; ++next)
        order_[std::get<3>(moved[next])] = rank++;
      order_[v] = rank++;
    }
    for (; next < moved.size(); ++next) order_[std::get<3>(moved[next])] = rank++;
  }

  static constexpr SimplexId kVisited = -1000;
  static constexpr int kMaxLocalOrderIterations = 1000;

  Reader& r_;
  const Topology& topo_;
  std::vector<SimplexId>& order_;
  const SimplexId n_;
  std::vector<SimplexId> maxima_;
  SparseVertexValues segmentation_, queue_mask_, local_order_;
  SparseVertexValues owner_;  // the propagation that reached a vertex (not its root)
  std::vector<Propagation> props_;
  UnionFind components_;  // over props_: the propagations merged into one
  std::vector<int32_t> parents_, neighbors_;
};

// After a pass, only the flattened vertices and their neighbours can have changed their flags:
// the others keep their relative order.
template <class Reader>
void RefreshFlags(Reader& reader, std::span<const SimplexId> order,
                  const std::vector<std::pair<SimplexId, std::vector<SimplexId>>>& segments,
                  std::vector<uint8_t>& flags) {
  std::vector<SimplexId> touched;
  for (const auto& segment : segments) {
    for (SimplexId v : segment.second) {
      touched.push_back(v);
      for (SimplexId u : reader.vertex_neighbors(v)) touched.push_back(u);
    }
  }
  for (SimplexId v : touched) flags[v] = ExtremumFlags(reader.vertex_neighbors(v), v, order);
}

// The vertices whose flags have `bit` and that are not authorized.
std::vector<SimplexId> Unauthorized(const std::vector<uint8_t>& flags, uint8_t bit,
                                    const std::vector<bool>& authorized) {
  std::vector<SimplexId> out;
  for (SimplexId v = 0; v < SimplexId(flags.size()); ++v) {
    if ((flags[v] & bit) && !authorized[v]) out.push_back(v);
  }
  return out;
}

// TTK's legacy simplification: from the kept minima, sweep the vertices in the order they are
// reached lowest first, each made no lower than the one before (value, and order = its position),
// then the same downwards from the kept maxima; again until no other extremum is left. `flags`
// holds the input's extrema and, at the end, the result's; `scalars` is by internal id.
template <class Reader>
absl::Status LegacySweeps(Reader& reader, const std::vector<bool>& authorized,
                          std::vector<uint8_t>& flags, std::vector<SimplexId>& order,
                          std::vector<double>& scalars, SimplificationStats& stats,
                          const RunContext& context) {
  const SimplexId n = SimplexId(order.size());
  std::vector<SimplexId> minima, maxima;  // the kept extrema: the seeds
  for (SimplexId v = 0; v < n; ++v) {
    if (authorized[v] && (flags[v] & kMinimum)) minima.push_back(v);
    if (authorized[v] && (flags[v] & kMaximum)) maxima.push_back(v);
  }
  std::vector<bool> seeded(n, false), visited(n);
  std::vector<SimplexId> sequence;
  sequence.reserve(n);
  for (SimplexId sweep = 0; sweep < n; ++sweep) {
    ++stats.sweeps;
    for (const bool upwards : {true, false}) {
      const std::vector<SimplexId>& seeds = upwards ? minima : maxima;
      if (seeds.empty()) continue;
      // The front, lowest order first upwards, highest first downwards (orders are distinct).
      std::priority_queue<std::pair<SimplexId, SimplexId>> front;
      const auto push = [&](SimplexId v) {
        front.emplace(upwards ? -order[v] : order[v], v);
        visited[v] = true;
      };
      std::fill(visited.begin(), visited.end(), false);
      for (SimplexId s : seeds) {
        seeded[s] = true;
        push(s);
      }
      sequence.clear();
      while (!front.empty()) {
        const SimplexId v = front.top().second;
        front.pop();
        sequence.push_back(v);
        for (SimplexId u : reader.vertex_neighbors(v)) {
          if (!visited[u]) push(u);
        }
      }
      for (size_t k = 0; k < sequence.size(); ++k) {
        const SimplexId v = sequence[k];
        if (k > 0) {
          const double previous = scalars[sequence[k - 1]];
          if (upwards ? scalars[v] <= previous : scalars[v] >= previous) scalars[v] = previous;
        }
        order[v] = upwards ? SimplexId(k) + 1 : n - 1 - SimplexId(k);
      }
    }
    // Converged when every extremum left is a seed.
    bool more = false;
    int64_t minima_left = 0, maxima_left = 0;
    for (SimplexId v = 0; v < n; ++v) {
      flags[v] = ExtremumFlags(reader.vertex_neighbors(v), v, order);
      minima_left += (flags[v] & kMinimum) != 0;
      maxima_left += (flags[v] & kMaximum) != 0;
      if (flags[v] != 0 && !seeded[v]) more = true;
    }
    more |= minima_left > int64_t(minima.size()) || maxima_left > int64_t(maxima.size());
    if (!more) return absl::OkStatus();
    RETURN_IF_ERROR(context.stop().status(kName));
  }
  return absl::OkStatus();
}

// The lower stars a simplification changed: those of the vertices it moved and of every
// neighbour whose lower link it reordered. A vertex's lower-star pairing reads nothing but how its
// lower neighbours compare with each other (the cells' keys), so a vertex whose lower neighbours
// are the same in both orders, in the same sequence, pairs as before. Around a flattened maximum
// the neighbours left outside lie below it in both orders and keep their stars, so far fewer
// stars are paired again than the moved vertices and all their neighbours.
// Ascending, distinct; `moved` must be distinct.
template <class Reader>
std::vector<SimplexId> ChangedLowerStars(Reader& reader, std::span<const SimplexId> before,
                                         std::span<const SimplexId> after,
                                         std::span<const SimplexId> moved) {
  std::vector<bool> seen(before.size(), false);  // moved, or a neighbour already compared
  for (SimplexId v : moved) seen[v] = true;
  std::vector<SimplexId> changed(moved.begin(), moved.end());
  std::vector<SimplexId> lower_before, lower_after;
  const auto lower_link = [&reader](SimplexId y, std::span<const SimplexId> order,
                                    std::vector<SimplexId>& out) {
    out.clear();
    for (SimplexId z : reader.vertex_neighbors(y)) {
      if (order[z] < order[y]) out.push_back(z);
    }
    std::sort(out.begin(), out.end(),
              [&](SimplexId a, SimplexId b) { return order[a] < order[b]; });
  };
  std::vector<SimplexId> around;  // x's row, kept while its neighbours' rows are read
  for (SimplexId x : moved) {
    const auto row = reader.vertex_neighbors(x);
    around.assign(row.begin(), row.end());
    for (SimplexId y : around) {
      if (seen[y]) continue;
      seen[y] = true;
      lower_link(y, before, lower_before);
      lower_link(y, after, lower_after);
      if (lower_before != lower_after) changed.push_back(y);
    }
  }
  std::sort(changed.begin(), changed.end());  // each vertex is listed once
  return changed;
}

void Invert(std::vector<SimplexId>& order) {
  const SimplexId last = SimplexId(order.size()) - 1;
  for (SimplexId& o : order) o = last - o;
}

std::string LinesDigest(size_t n, const std::function<void(size_t, std::string&)>& line) {
  StreamedText text;
  for (size_t v = 0; v < n; ++v) {
    line(v, text.buffer());
    text.Flush();
  }
  return text.HexDigest();
}

}  // namespace

std::string SimplificationResult::ScalarsDigest() const {
  return LinesDigest(scalars.size(), [&](size_t v, std::string& out) {
    char value[32];
    std::snprintf(value, sizeof(value), "%.17g", scalars[v]);
    absl::StrAppend(&out, v, " ", value, "\n");
  });
}

std::string SimplificationResult::OrderDigest() const {
  return LinesDigest(order.size(), [&](size_t v, std::string& out) {
    absl::StrAppend(&out, v, " ", order[v], "\n");
  });
}

RelationSet TopologicalSimplificationSwept() { return PersistenceDiagramDeclared(); }

RelationSet TopologicalSimplificationDeclared() {
  RelationSet s = PersistenceDiagramDeclared();
  s.Add(Relation::kVV);
  return s;
}

absl::Status ValidateSimplificationOptions(const SimplificationOptions& options) {
  if (!std::isfinite(options.threshold) || options.threshold < 0 ||
      (options.relative && options.threshold > 1)) {
    return absl::InvalidArgumentError(absl::StrCat("threshold: ", options.threshold, " is not a ",
                                                   options.relative
                                                       ? "fraction of the scalar range in [0, 1]"
                                                       : "finite, non-negative persistence"));
  }
  return absl::OkStatus();
}

// TTK's localized sweeps (LTS): the maxima that are not constraints removed, then the minima,
// each component flattened to its saddle's value, the maxima's components first, as TTK.
template <class Rows>
absl::Status LocalizedSweeps(const Topology& topo, Rows& rows, std::span<const SimplexId> order,
                             const std::vector<bool>& authorized, std::vector<uint8_t>& flags,
                             std::vector<SimplexId>& new_order, SimplificationResult& result,
                             const RunContext& context) {
  const SimplexId n = topo.num_vertices();
  // TTK decides which passes to run from the first neighbour of each constraint.
  bool has_maxima = false, has_minima = false;
  for (SimplexId v = 0; v < n && !(has_maxima && has_minima); ++v) {
    if (!authorized[v]) continue;
    const auto neighbors = rows.vertex_neighbors(v);
    if (neighbors.empty()) continue;
    (order[v] > order[neighbors[0]] ? has_maxima : has_minima) = true;
  }
  std::vector<std::pair<SimplexId, std::vector<SimplexId>>> segments;
  if (has_maxima) {
    Trace::Scope pass(context.trace.get(), "remove maxima", "phase");
    MaximaRemoval removal(rows, new_order, Unauthorized(flags, kMaximum, authorized));
    RETURN_IF_ERROR(removal.Run());
    result.stats.removed_maxima = removal.removed();
    segments = removal.TakeSegments();
    RefreshFlags(rows, new_order, segments, flags);
    for (const auto& [saddle, segment] : segments) {
      result.reordered.insert(result.reordered.end(), segment.begin(), segment.end());
    }
  }
  if (context.progress) context.progress(0.9);
  if (has_minima) {
    Trace::Scope pass(context.trace.get(), "remove minima", "phase");
    Invert(new_order);
    MaximaRemoval removal(rows, new_order, Unauthorized(flags, kMinimum, authorized));
    RETURN_IF_ERROR(removal.Run());
    Invert(new_order);
    result.stats.removed_minima = removal.removed();
    auto minima_segments = removal.TakeSegments();
    RefreshFlags(rows, new_order, minima_segments, flags);
    for (const auto& [saddle, segment] : minima_segments) {
      result.reordered.insert(result.reordered.end(), segment.begin(), segment.end());
    }
    // Values: the maxima's components first, then the minima's, as TTK.
    for (const auto& [saddle, segment] : segments) {
      for (SimplexId v : segment) {
        result.scalars[topo.vertex_input_id(v)] = result.scalars[topo.vertex_input_id(saddle)];
      }
    }
    segments = std::move(minima_segments);
  }
  for (const auto& [saddle, segment] : segments) {
    for (SimplexId v : segment) {
      result.scalars[topo.vertex_input_id(v)] = result.scalars[topo.vertex_input_id(saddle)];
    }
  }
  return absl::OkStatus();
}

template <TopologicalStructure Structure>
absl::StatusOr<SimplificationResult> RunTopologicalSimplification(
    Structure& structure, std::span<const SimplexId> order, std::span<const double> scalars,
    const SimplificationOptions& options, const RunContext& context) {
  RETURN_IF_ERROR(ValidateSimplificationOptions(options));
  const Topology& topo = structure.topology();
  const RunContext diagram_context = context.Slice(0, 0.8);
  SimplificationResult result;
  std::optional<VertexNeighbors> kept;
  if constexpr (!NeighborRows<Structure>::kInPlace) kept.emplace(topo);
  // The diagram's gradient is updated for the simplified complex (run_algorithm.cc), which
  // follows its tetrahedron -> triangle pairs.
  ASSIGN_OR_RETURN(result.diagram,
                   RunPersistenceDiagram(structure, order, scalars, diagram_context,
                                         kept ? &*kept : nullptr, GradientArrays::kPersistence));
  // The passes below read the kept neighbours and the gradient update a few stars: neither needs
  // the blocks the diagram left buffered, nor the memory its gradient and pairs freed, which the
  // allocator keeps in the consumers' arenas while the passes allocate on this thread: handing
  // it back here lowers the simplified Morse-Smale job's peak.
  EndPhase(structure);
  const auto [lo, hi] = std::minmax_element(scalars.begin(), scalars.end());
  result.threshold = options.relative ? options.threshold * (*hi - *lo) : options.threshold;
  result.legacy = options.legacy;

  // The kept pairs' vertices, as TTK's constraints.
  const SimplexId n = topo.num_vertices();
  std::vector<bool> authorized(n, false);
  for (const PersistencePair& p : result.diagram.pairs) {
    if (p.Persistence() < result.threshold) {
      ++result.stats.removed_pairs;
      continue;
    }
    ++result.stats.kept_pairs;
    for (SimplexId v : {p.birth, p.death}) {
      const SimplexId internal = topo.vertex_internal_id(v);
      result.stats.constraints += !authorized[internal];
      authorized[internal] = true;
    }
  }

  std::vector<SimplexId> new_order(order.begin(), order.end());
  result.scalars.assign(scalars.begin(), scalars.end());
  if (result.stats.constraints > 0) {
    Trace::Scope span(context.trace.get(), "simplify", "phase");
    // The input's extrema; the passes then refresh them only around what they flatten (LTS
    // scans every vertex before each pass).
    NeighborRows<Structure> rows(structure, kept ? &*kept : nullptr);
    std::vector<uint8_t> flags(n, 0);
    for (SimplexId v = 0; v < n; ++v) flags[v] = ExtremumFlags(rows.vertex_neighbors(v), v, order);
    if (options.legacy) {
      Trace::Scope pass(context.trace.get(), "legacy sweeps", "phase");
      std::vector<double> values(n);
      for (SimplexId v = 0; v < n; ++v) values[v] = scalars[topo.vertex_input_id(v)];
      RETURN_IF_ERROR(
          LegacySweeps(rows, authorized, flags, new_order, values, result.stats, context));
      for (SimplexId v = 0; v < n; ++v) result.scalars[topo.vertex_input_id(v)] = values[v];
    } else {
      RETURN_IF_ERROR(
          LocalizedSweeps(topo, rows, order, authorized, flags, new_order, result, context));
    }
    std::sort(result.reordered.begin(), result.reordered.end());
    result.reordered.erase(std::unique(result.reordered.begin(), result.reordered.end()),
                           result.reordered.end());
    result.changed_stars = ChangedLowerStars(rows, order, new_order, result.reordered);
    // Statistics of the simplified field: its extrema and what changed.
    for (SimplexId v = 0; v < n; ++v) {
      result.stats.minima += (flags[v] & kMinimum) != 0;
      result.stats.maxima += (flags[v] & kMaximum) != 0;
      const SimplexId input = topo.vertex_input_id(v);
      result.stats.changed_values += result.scalars[input] != scalars[input];
    }
  }
  result.order.resize(n);
  for (SimplexId v = 0; v < n; ++v) result.order[topo.vertex_input_id(v)] = new_order[v];
  result.internal_order = std::move(new_order);
  RETURN_IF_ERROR(context.stop().status(kName));
  if (context.progress) context.progress(1.0);
  return result;
}

#define ACTOPO_INSTANTIATE(S)                                                                \
  template absl::StatusOr<SimplificationResult> RunTopologicalSimplification(                \
      S&, std::span<const SimplexId>, std::span<const double>, const SimplificationOptions&, \
      const RunContext&);
ACTOPO_FOR_EACH_STRUCTURE(ACTOPO_INSTANTIATE)
#undef ACTOPO_INSTANTIATE

}  // namespace actopo
