// The static encoding of a partitioned tetrahedral mesh, built once and shared read-only by every
// structure and session on the mesh.
//
// This is the part of the localized data structure that is never recomputed: the blocks (vertex
// clusters, TopoCluster's "clusters"), the sorted edges and triangles (as runs, see Storage), each
// block's internal and external tetrahedra, block adjacency and boundary-triangle flags. Everything
// a block needs to compute any relation of its internal simplices on its own is here; the relations
// themselves are computed by block_relations.h.
//
//   ASSIGN_OR_RETURN(auto topology, Topology::Build(mesh, OctreeBlocks(mesh.points, {})));
//   SimplexId e = topology->FindEdge(u, v);   // internal ids, -1 if absent
//
// Ids. Vertices are renumbered so each block is a contiguous range (block order, then input id);
// tetrahedra are grouped by the block of their lowest vertex, then by that vertex, then input
// id (so a vertex's star sits in a few short runs whatever the file's cell order). A simplex
// belongs to the block of its lowest vertex. Edges and triangles are numbered in lexicographic
// order of their sorted vertex tuples; because blocks are vertex ranges in order, that numbering is
// also "by block, then lexicographic inside the block", so an edge's id is its block's first edge
// plus its rank inside the block (TopoCluster's numbering). Both permutations are kept so results
// can be reported in input ids.
//
// Storage. Faces (when built, TopologyOptions::faces) are stored as runs, not as tuples: the edges
// (a, *) of a vertex a are a run holding only their upper vertex, the triangles (a, b, *) of an
// edge (a, b) a run holding only their third vertex, both as 16-bit differences from a
// (NarrowIds); boundary flags are bits. The runs' starts are distances within small groups
// (RunStarts: 8 bits per 16 for an edge's triangles, 16 per 64 otherwise), and an edge's lowest
// vertex and a triangle's edge come from a RunLookup (1 byte per face). Tetrahedra are sorted
// tuples of 16-bit differences, 8 bytes each (NarrowTetrahedra); a block's external tetrahedra
// are 16-bit gaps (AscendingIdLists). About 30 bytes per tetrahedron in all, about 16 without
// faces (bench/RESULTS.md, "Static encoding").
#ifndef ACTOPO_SERVER_CORE_TOPOLOGY_H_
#define ACTOPO_SERVER_CORE_TOPOLOGY_H_

#include <algorithm>
#include <array>
#include <atomic>
#include <bit>
#include <cstdint>
#include <functional>
#include <iterator>
#include <memory>
#include <mutex>
#include <span>
#include <utility>
#include <vector>

#include "absl/status/statusor.h"
#include "server/core/mesh.h"
#include "server/core/parallel.h"
#include "server/core/progress.h"
#include "server/core/sync.h"
#include "server/core/trace.h"

namespace actopo {

// Sorts a simplex's n <= 4 vertex ids ascending in place (a sorting network: no call, no loop;
// run once per tetrahedron while encoding and per cell while digesting).
inline void SortVertexIds(SimplexId* s, int n) {
  const auto order = [s](int a, int b) {
    if (s[b] < s[a]) std::swap(s[a], s[b]);
  };
  if (n == 2) order(0, 1);
  if (n == 3) order(0, 1), order(1, 2), order(0, 1);
  if (n == 4) order(0, 1), order(2, 3), order(0, 2), order(1, 3), order(1, 2);
}

// A vector whose resize leaves the new elements uninitialized, for the arrays the encoding then
// writes in full on every thread: their pages are first touched by the threads that fill them,
// not zeroed on one thread first (the tetrahedron tuples are the encoding's largest array).
template <class T>
struct UninitializedAllocator : std::allocator<T> {
  template <class U>
  struct rebind {
    using other = UninitializedAllocator<U>;
  };
  template <class U, class... Args>
  void construct(U* p, Args&&... args) {
    if constexpr (sizeof...(Args) == 0) {
      ::new (static_cast<void*>(p)) U;
    } else {
      ::new (static_cast<void*>(p)) U(std::forward<Args>(args)...);
    }
  }
};
template <class T>
using FilledVector = std::vector<T, UninitializedAllocator<T>>;

class Topology;

struct TopologyOptions {
  int threads = 0;  // 0: DefaultThreads()
  // Called once Build has read the mesh's tetrahedra for the last time, before the edges and
  // triangles (the larger part of the encoding) are built. The topology it is given is not
  // finished, but its vertices and tetrahedra are: their ids, sorted tuples and both
  // permutations, so what else a caller needs of the input tetrahedra (e.g. InputCorners) can be
  // taken there. A caller may then free them (Build reads the mesh's tetrahedra, nothing else),
  // so they and the whole encoding are never resident together, which lowers the peak of a
  // critical points job, and of a server's load.
  std::function<void(const Topology&)> tetrahedra_read;
  // Per internal tetrahedron, the order its corners came in, when set: bits 2k..2k+1 of its byte
  // are the position in the input tetrahedron of corner k of its sorted tuple (what Morse-Smale
  // needs to number triangles as TTK does; InputCorners in morse_smale.h computes the same from a
  // mesh's tetrahedra). Taken while the tetrahedra are encoded, so no caller needs to keep them.
  std::vector<uint8_t>* input_corners = nullptr;
  // Lets Build hand the pages of mesh.tetrahedra back to the system as it reads them for the last
  // time (ReleasePages in process_memory.h). The caller must then not read them again, only free
  // them (in tetrahedra_read, say): the input tetrahedra and their encoded copy are then never
  // resident together, which would otherwise be the peak of a critical points run.
  bool release_tetrahedra = false;
  // Whether to build the edges and triangles (the "faces" step: most of the encoding's time and
  // about half its bytes). Without them the topology holds vertices, tetrahedra and
  // blocks: enough for the relations VV, VT, TV and VB and for critical points
  // (NeedsFaces in server/algorithms/registry.h); every edge and triangle accessor then must not
  // be called until Topology::EnsureFaces has built them (has_faces() says which).
  bool faces = true;
  // Records each step of the encoding as a span (category "encode": sort vertices, bucket
  // tetrahedra, sort tetrahedra, external tetrahedra, block neighbors, faces), when set.
  Trace* trace = nullptr;
};

// How Topology::EnsureFaces builds the edges and triangles a topology was built without.
struct FacesOptions {
  int threads = 0;         // 0: DefaultThreads()
  Trace* trace = nullptr;  // a span "faces" (category "encode") when set
};

// Bytes of each part of the static encoding.
struct TopologyBytes {
  int64_t vertices = 0;    // block of each vertex, both vertex permutations
  int64_t edges = 0;       // upper vertices, per-vertex run starts, lowest-vertex lookup
  int64_t triangles = 0;   // third vertices, per-edge run starts, edge lookup, boundary bits
  int64_t tetrahedra = 0;  // tetrahedron list and its internal -> input permutation
  int64_t blocks = 0;      // interval arrays, external tetrahedra, block adjacency
  int64_t total() const { return vertices + edges + triangles + tetrahedra + blocks; }
};

// The run holding an item when items are numbered run after run (edges by their lowest vertex,
// triangles by their edge): the largest r with begin[r] <= x, in two loads. Each item keeps its
// run's distance from the run of item 64 * (x / 64) in 8 bits (64 items span at most 64 runs
// and the empty runs between them: a vertex with no edge above it, an edge (a, b) with no triangle
// (a, b, c > b)); a distance that does not fit (stretches of hundreds of empty runs: unused
// vertices) falls back to a binary search over that stretch.
class RunLookup {
 public:
  void Build(std::span<const SimplexId> begin, SimplexId items, int threads);
  // `begin` as given to Build, or any array of the same values (RunStarts).
  template <class Begin>
  SimplexId Owner(const Begin& begin, SimplexId x) const {
    const SimplexId base = sample_[size_t(x) >> 6];
    const uint8_t offset = offset_[x];
    return offset != kFar ? base + offset : Search(begin, x);
  }
  int64_t bytes() const {
    return int64_t(sample_.size() * sizeof(SimplexId) + offset_.size() * sizeof(uint8_t));
  }

 private:
  static constexpr uint8_t kFar = 0xff;
  // The run lies between the runs of item 64 * (x / 64) and of the next sample (or last item).
  template <class Begin>
  [[gnu::noinline]] SimplexId Search(const Begin& begin, SimplexId x) const {
    SimplexId lo = sample_[size_t(x) >> 6], hi = sample_[(size_t(x) >> 6) + 1];
    while (lo < hi) {
      const SimplexId mid = lo + (hi - lo + 1) / 2;
      if (begin[mid] <= x) {
        lo = mid;
      } else {
        hi = mid - 1;
      }
    }
    return lo;
  }
  std::vector<SimplexId> sample_;  // run of item 64k; the last entry, run of the last item
  FilledVector<uint8_t> offset_;   // per item: its run - sample_[x / 64], or kFar
};

// The starts of consecutive runs (a non-decreasing array: a vertex's edges, an edge's triangles,
// a vertex's tetrahedra) in narrow distances instead of 32 bits: per group of 2^kShift entries the
// first (32 bits), and each entry's distance from it as a `Distance`. A group whose runs hold too
// many items for that (a vertex in 65,536 tetrahedra, 16 edges in 256 triangles) keeps its
// entries whole. Edges' triangle starts: 8 bits per 16 (1.25 bytes each), others 16 bits per 64.
template <class Distance, int kShift>
class RunStarts {
 public:
  size_t size() const { return distance_.size(); }
  SimplexId operator[](size_t i) const {
    const Group& group = groups_[i >> kShift];
    if (group.whole >= 0) [[unlikely]]
      return whole_[size_t(group.whole) + (i & kMask)];
    return group.first + distance_[i];
  }
  // Entries i and i + 1: a run's start and end.
  std::pair<SimplexId, SimplexId> Run(size_t i) const {
    if ((i & kMask) == kMask) return {(*this)[i], (*this)[i + 1]};
    const Group& group = groups_[i >> kShift];
    if (group.whole >= 0) [[unlikely]]
      return {whole_[size_t(group.whole) + (i & kMask)],
              whole_[size_t(group.whole) + (i & kMask) + 1]};
    return {group.first + distance_[i], group.first + distance_[i + 1]};
  }
  // Takes the values of `starts` (non-decreasing); ParallelFor over stretches of groups.
  void Assign(std::span<const SimplexId> starts, int threads);
  int64_t bytes() const {
    return int64_t(groups_.size() * sizeof(Group) + distance_.size() * sizeof(Distance) +
                   whole_.size() * sizeof(SimplexId));
  }

 private:
  static constexpr size_t kMask = (size_t(1) << kShift) - 1;
  struct Group {
    SimplexId first;  // the group's first entry
    int32_t whole;    // where its entries are in whole_, or -1 (stored as distances)
  };
  std::vector<Group> groups_;
  FilledVector<Distance> distance_;
  // The wide groups' entries, a group's worth each (the last group: fewer).
  std::vector<SimplexId> whole_;
};

// Which entries of an array are kept whole (the few whose differences do not fit 16 bits), and
// each one's slot among them: a 64-bit mask per 64 entries and a running count per 256 (0.14 bytes
// per entry), so a slot is at most four popcounts.
class WholeRank {
 public:
  // Marks entries [0, n) for which whole(i) is true; ParallelFor over stretches of groups.
  template <class IsWhole>
  void Build(size_t n, int threads, IsWhole&& whole);
  // The slot of a whole entry i: the whole entries before it.
  uint32_t Rank(size_t i) const {
    const size_t group = i >> 6;
    uint32_t rank = before_[i >> 8];
    for (size_t g = group & ~size_t(3); g < group; ++g) rank += std::popcount(masks_[g]);
    const uint64_t below = (uint64_t(1) << (i & 63)) - 1;
    return rank + uint32_t(std::popcount(masks_[group] & below));
  }
  int64_t bytes() const {
    return int64_t(masks_.size() * sizeof(uint64_t) + before_.size() * sizeof(uint32_t));
  }

 private:
  std::vector<uint64_t> masks_;   // per 64 entries: bit k, entry 64g + k is whole
  std::vector<uint32_t> before_;  // per 256 entries: the whole entries before them
};

template <class IsWhole>
void WholeRank::Build(size_t n, int threads, IsWhole&& whole) {
  masks_.resize((n + 63) / 64);
  constexpr int64_t kGroupsPerTask = 1 << 12;
  const int64_t tasks = (int64_t(masks_.size()) + kGroupsPerTask - 1) / kGroupsPerTask;
  ParallelFor(tasks, threads, [&](int64_t task, int) {
    const size_t end = std::min(masks_.size(), size_t(task + 1) * kGroupsPerTask);
    for (size_t g = size_t(task) * kGroupsPerTask; g < end; ++g) {
      uint64_t mask = 0;
      const size_t last = std::min(n, g * 64 + 64);
      for (size_t i = g * 64; i < last; ++i) mask |= uint64_t(whole(i)) << (i & 63);
      masks_[g] = mask;
    }
  });
  before_.resize((masks_.size() + 3) / 4);
  uint32_t wholes = 0;
  for (size_t g = 0; g < masks_.size(); ++g) {
    if (g % 4 == 0) before_[g / 4] = wholes;
    wholes += uint32_t(std::popcount(masks_[g]));
  }
}

// Ids stored as their difference from a base the reader knows (a face run's lowest vertex) in 16
// bits, 2 bytes each instead of 4; the few that do not fit (another block far in vertex order:
// 2-4% on the reference meshes) are kept whole beside them. Within a run the ids ascend from the
// same base, so a run's whole ids come last in it.
class NarrowIds {
 public:
  // The stored difference of an id kept whole.
  static constexpr uint16_t kWhole = 0xffff;
  static bool Fits(SimplexId id, SimplexId base) { return int64_t(id) - base < kWhole; }

  size_t size() const { return difference_.size(); }
  // The id at `i`, whose base is `base`.
  SimplexId Get(size_t i, SimplexId base) const {
    const uint16_t d = difference_[i];
    return d != kWhole ? base + d : Whole(i);
  }
  // The stored difference (kWhole: the id is Whole(i)).
  uint16_t difference(size_t i) const { return difference_[i]; }
  // Where `id` (from `base`) is among entries [begin, end), which ascend from that base: -1 if
  // absent. A scan over the differences, or over the whole ids at the end (runs are tens long).
  SimplexId Find(SimplexId begin, SimplexId end, SimplexId base, SimplexId id) const {
    const int64_t want = int64_t(id) - base;
    if (want < kWhole) {
      // The whole ids are above every difference: the first difference >= want decides.
      for (SimplexId i = begin; i < end; ++i) {
        if (difference_[i] >= want) return difference_[i] == want ? i : -1;
      }
      return -1;
    }
    for (SimplexId i = begin; i < end; ++i) {
      if (difference_[i] != kWhole) continue;
      const SimplexId whole = Whole(i);
      if (whole >= id) return whole == id ? i : -1;
    }
    return -1;
  }
  // As Find, for an id known to be there, at `from` or after it.
  SimplexId Seek(SimplexId from, SimplexId base, SimplexId id) const {
    const int64_t want = int64_t(id) - base;
    if (want < kWhole) {
      while (difference_[from] < want) ++from;
    } else {
      while (difference_[from] != kWhole || Whole(from) != id) ++from;
    }
    return from;
  }
  // An id kept whole.
  SimplexId Whole(size_t i) const { return whole_[rank_.Rank(i)]; }
  int64_t bytes() const {
    return int64_t(difference_.size() * sizeof(uint16_t) + whole_.size() * sizeof(SimplexId)) +
           rank_.bytes();
  }

  // Building: Resize (new entries unwritten), Set every entry with the index of the whole slot
  // it would take (wholes numbered in entry order), then Finish.
  void Reserve(size_t n) { difference_.reserve(n); }
  void Resize(size_t n, size_t wholes) {
    difference_.resize(n);
    whole_.resize(wholes);
  }
  size_t wholes() const { return whole_.size(); }
  // Stores `id` at `i`; when it does not fit, in whole slot `whole`, which is then advanced.
  void Set(size_t i, SimplexId id, SimplexId base, size_t& whole) {
    if (Fits(id, base)) {
      difference_[i] = uint16_t(id - base);
    } else {
      difference_[i] = kWhole;
      whole_[whole++] = id;
    }
  }
  void Finish(int threads) {
    rank_.Build(difference_.size(), threads, [&](size_t i) { return difference_[i] == kWhole; });
  }

 private:
  FilledVector<uint16_t> difference_;
  std::vector<SimplexId> whole_;  // the ids that do not fit, in entry order
  WholeRank rank_;
};

// Tetrahedra as sorted vertex tuples in 8 bytes each instead of 16. Tetrahedra are ordered by
// lowest vertex, so a tetrahedron's lowest vertex is stored as its difference from a base per
// group of 4096 (at or below every lowest vertex of the group), and its three others as their
// differences from the lowest, 16 bits each. A tetrahedron with a difference that does not fit
// (a vertex far in vertex order: another block) is kept whole beside them; its entry holds its
// slot there.
class NarrowTetrahedra {
 public:
  using Tuple = std::array<SimplexId, 4>;
  SimplexId size() const { return SimplexId(entries_.size()); }
  [[gnu::always_inline]] Tuple Get(SimplexId t) const {
    const Entry e = entries_[t];
    if (e[0] == kWhole) [[unlikely]]
      return Whole(e);
    const SimplexId a = lowest_[size_t(t) >> kLowestShift] + e[0];
    return {a, a + e[1], a + e[2], a + e[3]};
  }
  SimplexId lowest(SimplexId t) const {
    const uint16_t d = entries_[t][0];
    return d != kWhole ? lowest_[size_t(t) >> kLowestShift] + d : Whole(entries_[t])[0];
  }
  // Building, in parallel over disjoint ids: Start sizes the entries (unwritten) and takes each
  // group's base, `base(first id of the group)`: the lowest vertex of that tetrahedron, or any
  // vertex at or below every lowest vertex of the group (a looser one keeps more whole). Put
  // writes entry t from its sorted tuple and returns false when the tuple does not fit: the entry
  // is then marked whole, and the caller hands such tuples to Finish, in id order.
  template <class Base>
  void Start(SimplexId n, Base&& base) {
    entries_.resize(size_t(n));
    lowest_.resize((size_t(n) >> kLowestShift) + 1);
    for (size_t g = 0; g < lowest_.size(); ++g) {
      lowest_[g] = (g << kLowestShift) < size_t(n) ? base(SimplexId(g << kLowestShift)) : 0;
    }
  }
  bool Put(SimplexId t, const SimplexId* s) {
    const SimplexId base = lowest_[size_t(t) >> kLowestShift];
    // Unsigned: a lowest vertex below the base (a loose bound) does not fit either.
    if (uint64_t(int64_t(s[0]) - base) >= kWhole || uint64_t(int64_t(s[3]) - s[0]) >= kWhole) {
      entries_[t] = {kWhole, 0, 0, 0};
      return false;
    }
    entries_[t] = {uint16_t(s[0] - base), uint16_t(s[1] - s[0]), uint16_t(s[2] - s[0]),
                   uint16_t(s[3] - s[0])};
    return true;
  }
  void Finish(std::vector<Tuple> wholes, int threads);
  int64_t bytes() const {
    return int64_t(entries_.size() * sizeof(Entry) + lowest_.size() * sizeof(SimplexId) +
                   whole_.size() * sizeof(Tuple));
  }

 private:
  static constexpr uint16_t kWhole = 0xffff;
  // A lowest vertex per 4096 tetrahedra: a few kB that stay in cache, where one per 64 would be a
  // second cache miss per random read (a 16-bit difference spans 4096 tetrahedra's lowest
  // vertices, about 700 vertices, with room to spare).
  static constexpr int kLowestShift = 12;
  // Differences; a tetrahedron kept whole: {kWhole, its slot's low and high 16 bits, 0}.
  using Entry = std::array<uint16_t, 4>;
  // A tetrahedron kept whole (out of line: Get stays small).
  [[gnu::noinline]] Tuple Whole(Entry e) const { return whole_[size_t(e[1]) | size_t(e[2]) << 16]; }
  FilledVector<Entry> entries_;
  std::vector<SimplexId> lowest_;  // per 4096: Start's base of the first
  std::vector<Tuple> whole_;       // the tetrahedra kept whole, in id order
};

// Lists of ascending ids (each block's external tetrahedra) as 16-bit gaps from the previous id
// of the list, read in order; a gap that does not fit (the next tetrahedron's lowest vertex in
// another block, far in id) keeps its id whole beside them.
class AscendingIdLists {
 public:
  static constexpr uint16_t kWhole = 0xffff;
  class Iterator {
   public:
    using iterator_category = std::input_iterator_tag;
    using value_type = SimplexId;
    using difference_type = std::ptrdiff_t;
    using pointer = void;
    using reference = SimplexId;
    Iterator() = default;
    Iterator(const uint16_t* gap, const SimplexId* whole) : gap_(gap), whole_(whole) {}
    SimplexId operator*() const { return *gap_ != kWhole ? previous_ + *gap_ : *whole_; }
    Iterator& operator++() {
      previous_ = *gap_ != kWhole ? previous_ + *gap_ : *whole_++;
      ++gap_;
      return *this;
    }
    Iterator operator++(int) {
      Iterator before = *this;
      ++*this;
      return before;
    }
    bool operator==(const Iterator& other) const { return gap_ == other.gap_; }

   private:
    const uint16_t* gap_ = nullptr;
    const SimplexId* whole_ = nullptr;
    SimplexId previous_ = 0;  // the first id's gap is from 0
  };
  struct List {
    Iterator first, last;
    size_t count;
    Iterator begin() const { return first; }
    Iterator end() const { return last; }
    size_t size() const { return count; }
    bool empty() const { return count == 0; }
  };
  List list(int32_t k) const {
    const uint16_t* gaps = gaps_.data();
    return {Iterator(gaps + offsets_[k], whole_.data() + whole_offsets_[k]),
            Iterator(gaps + offsets_[k + 1], nullptr), size_t(offsets_[k + 1] - offsets_[k])};
  }
  // Takes lists [offsets[k], offsets[k + 1]) of `ids`; ParallelFor over the lists.
  void Assign(std::span<const SimplexId> offsets, std::span<const SimplexId> ids, int threads);
  int64_t bytes() const {
    return int64_t((offsets_.size() + whole_offsets_.size() + whole_.size()) * sizeof(SimplexId) +
                   gaps_.size() * sizeof(uint16_t));
  }

 private:
  std::vector<SimplexId> offsets_, whole_offsets_;  // per list + 1: into gaps_, into whole_
  FilledVector<uint16_t> gaps_;
  std::vector<SimplexId> whole_;
};

class Topology {
 public:
  // `vertex_block` gives the block of each input vertex (dense ids 0..B-1, e.g. OctreeBlocks).
  // The mesh must be valid (ValidateMesh). Build reads its tetrahedra only, so a caller that has
  // its blocks may free the points first (then vertex_block.size() is the vertex count). Reports
  // phase "encode" and stops (CANCELLED or DEADLINE_EXCEEDED, nothing kept) between its steps when
  // `progress` says so.
  static absl::StatusOr<std::shared_ptr<const Topology>> Build(
      const Mesh& mesh, std::span<const int32_t> vertex_block, const TopologyOptions& options = {},
      const Progress& progress = {});

  // Builds the edges and triangles of a topology built without them (TopologyOptions::faces =
  // false), as Build would have: once, whoever asks first; a concurrent caller waits for that
  // build and returns at once after it. Thread-safe beside readers of the rest of the topology,
  // which the build does not touch. Reports phase "faces" and stops when `progress` says so
  // (CANCELLED or DEADLINE_EXCEEDED, nothing kept: the next call starts over). Sessions that
  // never read an edge or a triangle (critical points) then never pay its time or its memory.
  absl::Status EnsureFaces(const Progress& progress = {}, const FacesOptions& options = {}) const;

  SimplexId num_vertices() const { return num_vertices_; }
  SimplexId num_edges() const {
    return has_faces() ? static_cast<SimplexId>(edge_upper_.size()) : 0;
  }
  SimplexId num_triangles() const {
    return has_faces() ? static_cast<SimplexId>(triangle_third_.size()) : 0;
  }
  SimplexId num_tetrahedra() const { return tets_.size(); }
  int32_t num_blocks() const { return num_blocks_; }
  // Whether edges and triangles were built (TopologyOptions::faces, EnsureFaces); without them
  // num_edges() and num_triangles() are 0. Once true, stays true.
  bool has_faces() const { return has_faces_.load(std::memory_order_acquire); }
  SimplexId num_simplices(int dimension) const;

  // Sorted vertex tuples (internal ids). Edges and triangles are decoded (by value); when their
  // lowest vertex is already known, edge_upper and triangle_third are one load.
  [[gnu::always_inline]] std::array<SimplexId, 2> edge(SimplexId e) const {
    const SimplexId a = edge_lowest(e);
    return {a, edge_upper(e, a)};
  }
  [[gnu::always_inline]] std::array<SimplexId, 3> triangle(SimplexId f) const {
    const SimplexId e = triangle_edge(f);
    const SimplexId a = edge_lowest(e);
    return {a, edge_upper(e, a), triangle_third(f, a)};
  }
  // Triangle f's three edges (a, b), (a, c), (b, c): the first is the one the encoding keeps
  // with f, the other two are looked up (FindEdge).
  std::array<SimplexId, 3> triangle_edges(SimplexId f) const {
    const SimplexId ab = triangle_edge(f);
    const SimplexId a = edge_lowest(ab), b = edge_upper(ab, a);
    const SimplexId c = triangle_third(f, a);
    return {ab, FindEdge(a, c), FindEdge(b, c)};
  }
  [[gnu::always_inline]] std::array<SimplexId, 4> tetrahedron(SimplexId t) const {
    return tets_.Get(t);
  }
  bool triangle_on_boundary(SimplexId f) const {
    return (triangle_boundary_[size_t(f) >> 6] >> (f & 63)) & 1;
  }
  // Whether some triangle has three tetrahedra or more (a non-manifold mesh). When not, a
  // triangle has one tetrahedron on the boundary and two elsewhere.
  bool has_crowded_triangles() const { return crowded_triangles_; }
  // Edge (a, b): a (its lowest vertex) and b. Triangle (a, b, c): its edge (a, b) and c. The
  // upper and third vertices are stored relative to a (NarrowIds), which the caller passes.
  SimplexId edge_lowest(SimplexId e) const { return edge_lowest_.Owner(vertex_edge_begin_, e); }
  SimplexId edge_upper(SimplexId e, SimplexId a) const { return edge_upper_.Get(e, a); }
  SimplexId triangle_edge(SimplexId f) const {
    return triangle_edge_.Owner(edge_triangle_begin_, f);
  }
  SimplexId triangle_third(SimplexId f, SimplexId a) const { return triangle_third_.Get(f, a); }
  // The stored runs themselves, for scans that know the lowest vertex (block relations).
  const NarrowIds& edge_uppers() const { return edge_upper_; }
  const NarrowIds& triangle_thirds() const { return triangle_third_; }

  // Tuple -> id; the internal vertex ids must be sorted ascending. -1 if no such simplex.
  SimplexId FindEdge(SimplexId a, SimplexId b) const;
  SimplexId FindTriangle(SimplexId a, SimplexId b, SimplexId c) const;
  SimplexId FindTetrahedron(SimplexId a, SimplexId b, SimplexId c, SimplexId d) const;
  // The tetrahedra whose lowest vertex is v: ids [first, second), ascending (a run of v's
  // block's internal tetrahedra; two loads). Every tetrahedron of v's star not in it has a lower
  // id.
  std::pair<SimplexId, SimplexId> lowest_vertex_tetrahedra(SimplexId v) const;
  // The tetrahedra of triangle f, ascending, when its lowest vertex's run above holds all of
  // them (their fourth vertex is above f's lowest): their count, one on the boundary, two
  // elsewhere. -1 when some have their lowest vertex below f's, or on a mesh with crowded
  // triangles: the caller then reads the star of f's lowest vertex (VT). No relation is read.
  int TriangleTetrahedraInRun(SimplexId f, std::array<SimplexId, 2>& out) const;

  // Block of a simplex: the block of its lowest vertex.
  int32_t vertex_block(SimplexId v) const { return vertex_block_[v]; }
  int32_t block_of(int dimension, SimplexId s) const;

  // Internal simplices of block b: [begin(b), begin(b + 1)).
  SimplexId block_vertex_begin(int32_t b) const { return block_vertex_begin_[b]; }
  SimplexId block_edge_begin(int32_t b) const { return vertex_edge_begin_[block_vertex_begin_[b]]; }
  SimplexId block_triangle_begin(int32_t b) const {
    return vertex_first_triangle(block_vertex_begin_[b]);
  }
  SimplexId block_tetrahedron_begin(int32_t b) const { return block_tet_begin_[b]; }
  SimplexId block_begin(int dimension, int32_t b) const;
  SimplexId block_size(int dimension, int32_t b) const {
    return block_begin(dimension, b + 1) - block_begin(dimension, b);
  }
  // Edges (resp. triangles) whose lowest vertex is v: [first(v), first(v + 1)), ascending upper
  // vertex (resp. lexicographic). Triangles (a, b, *) of edge e = (a, b): [first(e), first(e + 1)),
  // ascending third vertex.
  SimplexId vertex_first_edge(SimplexId v) const { return vertex_edge_begin_[v]; }
  SimplexId vertex_first_triangle(SimplexId v) const {
    return edge_triangle_begin_[vertex_edge_begin_[v]];
  }
  SimplexId edge_first_triangle(SimplexId e) const { return edge_triangle_begin_[e]; }

  // Tetrahedra whose lowest vertex lies in an earlier block but which have a vertex in b,
  // ascending. All of them have smaller ids than b's internal tetrahedra.
  AscendingIdLists::List external_tetrahedra(int32_t b) const { return external_tets_.list(b); }
  // Blocks sharing a tetrahedron with b, ascending, b excluded.
  std::span<const int32_t> block_neighbors(int32_t b) const {
    return {block_neighbors_.data() + block_neighbor_offsets_[b],
            block_neighbors_.data() + block_neighbor_offsets_[b + 1]};
  }

  // Permutations between internal and input ids.
  SimplexId vertex_input_id(SimplexId v) const { return vertex_input_id_[v]; }
  SimplexId vertex_internal_id(SimplexId input) const { return vertex_internal_id_[input]; }
  SimplexId tetrahedron_input_id(SimplexId t) const { return tet_input_id_[t]; }
  // Built on first use (the service's tetrahedron ids; no algorithm needs it); thread-safe.
  SimplexId tetrahedron_internal_id(SimplexId input) const;
  std::span<const SimplexId> vertex_input_ids() const { return vertex_input_id_; }
  std::span<const SimplexId> tetrahedron_input_ids() const { return tet_input_id_; }

  TopologyBytes bytes() const;

 private:
  // Build's steps (phase "encode") and the state they hand on to each other; see topology.cc.
  struct Encoder;

  Topology() = default;
  // Frees what a stopped face build left (EnsureFaces).
  void ClearFaces();

  SimplexId num_vertices_ = 0;
  int32_t num_blocks_ = 0;
  // The face arrays below (vertex_edge_begin_ to triangle_boundary_) are written by Build, or
  // once by EnsureFaces under faces_mu_ on a topology others already read; either way before
  // has_faces_ is set (release), and never after. Readers of them test has_faces() (acquire)
  // first, or were handed the topology after it was set.
  std::atomic<bool> has_faces_ = false;
  mutable Mutex faces_mu_;
  std::vector<int32_t> vertex_block_;            // by internal vertex
  std::vector<SimplexId> block_vertex_begin_;    // B + 1
  std::vector<SimplexId> block_tet_begin_;       // B + 1
  RunStarts<uint16_t, 6> vertex_edge_begin_;     // V + 1: run of edges (v, *)
  NarrowIds edge_upper_;                         // 1 per edge: b of (a, b), from a
  RunLookup edge_lowest_;                        // edge -> a
  RunStarts<uint8_t, 4> edge_triangle_begin_;    // E + 1: run of triangles (a, b, *)
  NarrowIds triangle_third_;                     // 1 per triangle: c of (a, b, c), from a
  RunLookup triangle_edge_;                      // triangle -> edge (a, b)
  std::vector<uint64_t> triangle_boundary_;      // 1 bit per triangle
  bool crowded_triangles_ = false;               // has_crowded_triangles()
  NarrowTetrahedra tets_;                        // sorted tuples
  RunStarts<uint16_t, 6> vertex_tet_begin_;      // V + 1: run of tetrahedra (v, *)
  AscendingIdLists external_tets_;               // per block
  std::vector<int32_t> block_neighbor_offsets_;  // B + 1
  std::vector<int32_t> block_neighbors_;
  std::vector<SimplexId> vertex_input_id_, vertex_internal_id_;
  FilledVector<SimplexId> tet_input_id_;
  mutable std::once_flag tet_internal_once_;
  mutable std::vector<SimplexId> tet_internal_id_;
};

}  // namespace actopo

#endif  // ACTOPO_SERVER_CORE_TOPOLOGY_H_
