#include "server/core/topology.h"

#include <algorithm>
#include <array>
#include <bit>
#include <limits>

#include "absl/strings/str_cat.h"
#include "server/core/parallel.h"
#include "server/core/process_memory.h"
#include "server/core/status_macros.h"

namespace actopo {
namespace {

// Bytes in use: the face arrays keep an untouched upper-bound reservation (see Build), which
// costs address space, not memory.
template <class T, class A>
int64_t VectorBytes(const std::vector<T, A>& v) {
  return static_cast<int64_t>(v.size() * sizeof(T));
}

// Edges and triangles owned by one block (lowest vertex inside it), sorted and unique, as the
// runs the topology stores, with a boundary flag per triangle (one tetrahedron around it).
struct BlockFaces {
  std::vector<uint64_t> edges;             // (a << 32) | b
  std::vector<SimplexId> edge_triangles;   // per edge: its triangles (a, b, *)
  std::vector<SimplexId> triangle_third;   // c of each triangle (a, b, c), in order
  std::vector<uint8_t> triangle_boundary;  // per triangle
  bool crowded = false;                    // a triangle with three tetrahedra or more
  // Upper and third vertices too far above their lowest vertex for 16 bits (NarrowIds).
  size_t whole_uppers = 0, whole_thirds = 0;
};

// Offsets of per-item counts: out[0] = 0, out[i + 1] = out[i] + counts[i].
template <class T>
std::vector<T> PrefixSum(const std::vector<T>& counts) {
  std::vector<T> out(counts.size() + 1, 0);
  for (size_t i = 0; i < counts.size(); ++i) out[i + 1] = out[i] + counts[i];
  return out;
}

// Stable bucket sort of the items 0 .. n-1 over `threads` contiguous chunks in parallel:
// for_each_bucket(i, emit) calls emit(bucket) once per bucket item i goes to. Fills `offsets`
// (buckets + 1) and `items` (per bucket, its items ascending), and calls placed(i, slot, chunk)
// as item i is written to items[slot], on the thread that writes it. As the placing goes on,
// done(from, to) says that items [from, to) of a chunk will not be looked at again (cumulative:
// `from` is the chunk's first item).
template <class ForEachBucket, class Items, class Placed, class Done>
void BucketItems(int64_t n, int32_t buckets, int threads, ForEachBucket&& for_each_bucket,
                 std::vector<SimplexId>& offsets, Items& items, Placed&& placed, Done&& done) {
  constexpr int64_t kDoneStride = int64_t(1) << 16;
  const int chunks = int(std::clamp<int64_t>(threads, 1, std::max<int64_t>(n, 1)));
  const auto chunk_begin = [&](int64_t c) { return n * c / chunks; };
  // Per chunk: its count per bucket, then where its items of that bucket go.
  std::vector<std::vector<SimplexId>> cursor(chunks, std::vector<SimplexId>(buckets, 0));
  ParallelFor(chunks, chunks, [&](int64_t c, int) {
    std::vector<SimplexId>& count = cursor[c];
    for (int64_t i = chunk_begin(c); i < chunk_begin(c + 1); ++i) {
      for_each_bucket(i, [&](int32_t b) { ++count[b]; });
    }
  });
  offsets.assign(size_t(buckets) + 1, 0);
  SimplexId total = 0;
  for (int32_t b = 0; b < buckets; ++b) {
    offsets[b] = total;
    for (int c = 0; c < chunks; ++c) {
      const SimplexId count = cursor[c][b];
      cursor[c][b] = total;
      total += count;
    }
  }
  offsets[buckets] = total;
  items.resize(total);
  ParallelFor(chunks, chunks, [&](int64_t c, int) {
    std::vector<SimplexId>& at = cursor[c];
    const int64_t first = chunk_begin(c), end = chunk_begin(c + 1);
    for (int64_t i = first; i < end; ++i) {
      for_each_bucket(i, [&](int32_t b) {
        const SimplexId slot = at[b]++;
        items[slot] = SimplexId(i);
        placed(i, slot, int(c));
      });
      if ((i - first + 1) % kDoneStride == 0) done(first, i + 1);
    }
    done(first, end);
  });
}

}  // namespace

void RunLookup::Build(std::span<const SimplexId> begin, SimplexId items, int threads) {
  // The largest r with begin[r] <= x (begin.back() == items > x bounds it).
  const auto run_of = [&](SimplexId x) {
    return SimplexId(std::upper_bound(begin.begin(), begin.end(), x) - begin.begin()) - 1;
  };
  const int64_t groups = (int64_t(items) + 63) / 64;
  sample_.assign(size_t(groups) + 1, 0);
  offset_.resize(size_t(items));  // every entry is written below
  // Stretches of groups in parallel, each starting from its first item's run.
  constexpr int64_t kGroupsPerTask = 1 << 12;
  ParallelFor((groups + kGroupsPerTask - 1) / kGroupsPerTask, threads, [&](int64_t task, int) {
    const SimplexId first = SimplexId(task * kGroupsPerTask * 64);
    const SimplexId last = SimplexId(std::min<int64_t>(items, (task + 1) * kGroupsPerTask * 64));
    SimplexId run = run_of(first);
    for (SimplexId x = first; x < last; ++x) {
      while (begin[run + 1] <= x) ++run;
      if (x % 64 == 0) sample_[x / 64] = run;
      const SimplexId offset = run - sample_[x / 64];
      offset_[x] = offset < kFar ? uint8_t(offset) : kFar;
    }
  });
  if (items > 0) sample_.back() = run_of(items - 1);
}

void NarrowTetrahedra::Finish(std::vector<Tuple> wholes, int threads) {
  whole_ = std::move(wholes);
  // Each whole entry gets its slot: the whole entries before it (they are in id order).
  constexpr size_t kPerTask = size_t(1) << 18;
  const int64_t tasks = int64_t((entries_.size() + kPerTask - 1) / kPerTask);
  const auto range = [&](int64_t task) {
    return std::pair(size_t(task) * kPerTask,
                     std::min(entries_.size(), size_t(task + 1) * kPerTask));
  };
  std::vector<size_t> before(size_t(tasks) + 1, 0);
  ParallelFor(tasks, threads, [&](int64_t task, int) {
    const auto [first, end] = range(task);
    for (size_t t = first; t < end; ++t) before[task + 1] += entries_[t][0] == kWhole;
  });
  for (int64_t task = 0; task < tasks; ++task) before[task + 1] += before[task];
  ParallelFor(tasks, threads, [&](int64_t task, int) {
    const auto [first, end] = range(task);
    size_t slot = before[task];
    for (size_t t = first; t < end; ++t) {
      if (entries_[t][0] != kWhole) continue;
      entries_[t] = {kWhole, uint16_t(slot), uint16_t(slot >> 16), 0};
      ++slot;
    }
  });
}

void AscendingIdLists::Assign(std::span<const SimplexId> offsets, std::span<const SimplexId> ids,
                              int threads) {
  const int64_t lists = int64_t(offsets.size()) - 1;
  offsets_.assign(offsets.begin(), offsets.end());
  gaps_.resize(ids.size());  // every entry is written below
  // Each list's gaps and how many ids it keeps whole, then the whole ids in list order.
  whole_offsets_.assign(offsets.size(), 0);
  ParallelFor(lists, threads, [&](int64_t k, int) {
    SimplexId previous = 0, wholes = 0;
    for (SimplexId i = offsets[k]; i < offsets[k + 1]; ++i) {
      const int64_t gap = int64_t(ids[i]) - previous;
      gaps_[i] = gap >= 0 && gap < kWhole ? uint16_t(gap) : kWhole;
      wholes += gaps_[i] == kWhole;
      previous = ids[i];
    }
    whole_offsets_[k + 1] = wholes;
  });
  for (int64_t k = 0; k < lists; ++k) whole_offsets_[k + 1] += whole_offsets_[k];
  whole_.resize(size_t(whole_offsets_.back()));
  ParallelFor(lists, threads, [&](int64_t k, int) {
    SimplexId slot = whole_offsets_[k];
    for (SimplexId i = offsets[k]; i < offsets[k + 1]; ++i) {
      if (gaps_[i] == kWhole) whole_[slot++] = ids[i];
    }
  });
}

template <class Distance, int kShift>
void RunStarts<Distance, kShift>::Assign(std::span<const SimplexId> starts, int threads) {
  constexpr size_t kSize = size_t(1) << kShift;
  const size_t n = starts.size(), groups = (n + kSize - 1) / kSize;
  groups_.resize(groups);
  distance_.resize(n);  // every entry of a narrow group is written below
  const auto last = [n](size_t g) { return std::min(n, (g + 1) * kSize) - 1; };
  constexpr int64_t kGroupsPerTask = 1 << 12;
  const int64_t tasks = (int64_t(groups) + kGroupsPerTask - 1) / kGroupsPerTask;
  ParallelFor(tasks, threads, [&](int64_t task, int) {
    const size_t end = std::min(groups, size_t(task + 1) * kGroupsPerTask);
    for (size_t g = size_t(task) * kGroupsPerTask; g < end; ++g) {
      const SimplexId first = starts[g * kSize];
      const bool wide = int64_t(starts[last(g)]) - first > std::numeric_limits<Distance>::max();
      groups_[g] = {first, wide ? 0 : -1};
      if (wide) continue;
      for (size_t i = g * kSize; i <= last(g); ++i) distance_[i] = Distance(starts[i] - first);
    }
  });
  whole_.clear();
  for (size_t g = 0; g < groups; ++g) {
    if (groups_[g].whole < 0) continue;
    groups_[g].whole = int32_t(whole_.size());
    whole_.insert(whole_.end(), starts.begin() + g * kSize, starts.begin() + last(g) + 1);
  }
}

template class RunStarts<uint16_t, 6>;
template class RunStarts<uint8_t, 4>;

SimplexId Topology::tetrahedron_internal_id(SimplexId input) const {
  std::call_once(tet_internal_once_, [this] {
    tet_internal_id_.resize(tet_input_id_.size());
    for (size_t t = 0; t < tet_input_id_.size(); ++t) {
      tet_internal_id_[tet_input_id_[t]] = SimplexId(t);
    }
  });
  return tet_internal_id_[input];
}

SimplexId Topology::num_simplices(int dimension) const {
  switch (dimension) {
    case 0: return num_vertices();
    case 1: return num_edges();
    case 2: return num_triangles();
    default: return num_tetrahedra();
  }
}

int32_t Topology::block_of(int dimension, SimplexId s) const {
  switch (dimension) {
    case 0: return vertex_block_[s];
    case 1: return vertex_block_[edge_lowest(s)];
    case 2: return vertex_block_[edge_lowest(triangle_edge(s))];
    default: return vertex_block_[tets_.lowest(s)];
  }
}

SimplexId Topology::block_begin(int dimension, int32_t b) const {
  switch (dimension) {
    case 0: return block_vertex_begin_[b];
    case 1: return block_edge_begin(b);
    case 2: return block_triangle_begin(b);
    default: return block_tet_begin_[b];
  }
}

SimplexId Topology::FindEdge(SimplexId a, SimplexId b) const {
  // Edges starting at a are few (tens), sorted by their upper vertex: a short linear scan.
  const auto [begin, end] = vertex_edge_begin_.Run(a);
  return edge_upper_.Find(begin, end, a, b);
}

SimplexId Topology::FindTriangle(SimplexId a, SimplexId b, SimplexId c) const {
  const SimplexId e = FindEdge(a, b);
  if (e < 0) return -1;
  const auto [begin, end] = edge_triangle_begin_.Run(e);
  return triangle_third_.Find(begin, end, a, c);
}

std::pair<SimplexId, SimplexId> Topology::lowest_vertex_tetrahedra(SimplexId v) const {
  return vertex_tet_begin_.Run(v);
}

int Topology::TriangleTetrahedraInRun(SimplexId f, std::array<SimplexId, 2>& out) const {
  if (crowded_triangles_) return -1;
  const auto [a, b, c] = triangle(f);
  const int expected = triangle_on_boundary(f) ? 1 : 2;
  const auto [first, end] = lowest_vertex_tetrahedra(a);
  int n = 0;
  for (SimplexId t = first; t < end && n < expected; ++t) {
    const auto s = tets_.Get(t);  // s[0] == a
    if ((s[1] == b && (s[2] == c || s[3] == c)) || (s[2] == b && s[3] == c)) out[n++] = t;
  }
  return n == expected ? n : -1;
}

SimplexId Topology::FindTetrahedron(SimplexId a, SimplexId b, SimplexId c, SimplexId d) const {
  const auto [begin, end] = lowest_vertex_tetrahedra(a);
  for (SimplexId t = begin; t < end; ++t) {
    const auto s = tets_.Get(t);
    if (s[1] == b && s[2] == c && s[3] == d) return t;
  }
  return -1;
}

TopologyBytes Topology::bytes() const {
  TopologyBytes b;
  b.vertices =
      VectorBytes(vertex_block_) + VectorBytes(vertex_input_id_) + VectorBytes(vertex_internal_id_);
  // Faces being built by EnsureFaces are not read (has_faces_); their memory is the caller's.
  if (has_faces()) {
    b.edges = edge_upper_.bytes() + vertex_edge_begin_.bytes() + edge_lowest_.bytes();
    b.triangles = triangle_third_.bytes() + edge_triangle_begin_.bytes() + triangle_edge_.bytes() +
                  VectorBytes(triangle_boundary_);
  }
  // tet_internal_id_ is built on first use by the service; not part of what algorithms need.
  b.tetrahedra = tets_.bytes() + vertex_tet_begin_.bytes() + VectorBytes(tet_input_id_);
  b.blocks = VectorBytes(block_vertex_begin_) + VectorBytes(block_tet_begin_) +
             external_tets_.bytes() + VectorBytes(block_neighbor_offsets_) +
             VectorBytes(block_neighbors_);
  return b;
}

namespace {

constexpr std::string_view kPhase = "encode";  // the progress phase of Topology::Build

// Blocks per window of the face computation (see Topology::Encoder::ReserveFaces).
constexpr int32_t kWindow = 256;

// Checks one block id per vertex, each in [0, nv); returns the block count for SortVertices.
absl::StatusOr<int32_t> CountBlocks(std::span<const int32_t> vertex_block, SimplexId nv) {
  if (vertex_block.size() != static_cast<size_t>(nv)) {
    return absl::InvalidArgumentError(
        absl::StrCat("blocks: ", vertex_block.size(), " block ids for ", nv, " vertices"));
  }
  int32_t num_blocks = 0;
  for (SimplexId v = 0; v < nv; ++v) {
    if (vertex_block[v] < 0 || vertex_block[v] >= nv) {
      return absl::InvalidArgumentError(
          absl::StrCat("blocks: vertex ", v, " has block id ", vertex_block[v]));
    }
    num_blocks = std::max(num_blocks, vertex_block[v] + 1);
  }
  return num_blocks;
}

}  // namespace

// The steps of Build (progress phase "encode"), declared in the order Build runs them, and the
// state they hand on. Each step fills some of the topology's arrays; Build reports progress
// between steps and stops there when told to.
struct Topology::Encoder {
  // Per thread, reused from block to block while computing faces.
  struct Scratch {
    std::vector<SimplexId> star_begin, star;       // star: positions in tuples
    std::vector<std::array<SimplexId, 4>> tuples;  // the block's tetrahedra, decoded
    std::vector<SimplexId> upper;
    struct Pair {
      uint64_t key;    // (b << 32) | c
      uint32_t count;  // tetrahedra around the triangle (v, b, c)
    };
    std::vector<Pair> pairs;
    // CollectUpperFaces' hash table: keys (kNoKey when free), counts, the slots in use.
    std::vector<uint64_t> slot_key;
    std::vector<uint32_t> slot_count;
    std::vector<uint32_t> used;
  };
  using Tuple = std::array<SimplexId, 4>;
  // Per thread, reused from stretch to stretch while sorting tetrahedra.
  struct StretchTets {
    std::vector<SimplexId> at, inputs;
    std::vector<uint8_t> corners;
    std::vector<std::pair<SimplexId, std::array<SimplexId, 4>>> wholes;  // (id, tuple)
  };

  const Mesh& mesh;
  std::span<const int32_t> vertex_block;  // by input vertex
  SimplexId nv, nt;
  int32_t num_blocks;
  int threads;
  Topology& t;
  const TopologyOptions& options;  // input_corners and release_tetrahedra
  // Allocated by ReserveFaces for the window loop.
  std::vector<BlockFaces> faces;                // per block of the current window
  std::vector<std::vector<int32_t>> neighbors;  // per block, until ListBlockNeighbors
  std::vector<Scratch> scratch;                 // per thread
  // The tetrahedra are bucketed by stretches of vertices: vertex v is in stretch
  // v / stretch_vertices, and stretch_tet_begin (stretches + 1) says where each stretch's
  // tetrahedra (those whose lowest vertex it holds) start.
  static constexpr int64_t kStretchTets = int64_t(1) << 16;             // on average
  static constexpr SimplexId kMaxStretchVertices = SimplexId(1) << 15;  // offsets fit 16 bits
  SimplexId stretch_vertices = 1;
  std::vector<SimplexId> stretch_tet_begin;
  // The sorted tuples bucketed by stretch, until the sort within each stretch encodes them
  // (NarrowTetrahedra), in 8 bytes each: the lowest vertex's offset in its stretch and the
  // others' differences from it, 16 bits each. One that does not fit is {kWhole, its index's low
  // and high 16 bits, chunk} into its chunk's `bucketed_wholes`.
  using Bucketed = std::array<uint16_t, 4>;
  static constexpr uint16_t kWhole = 0xffff;
  FilledVector<Bucketed> bucketed;
  std::vector<std::vector<Tuple>> bucketed_wholes;  // per chunk of BucketTetrahedra
  // The run starts in 32 bits while they are written (V + 1, E + 1, V + 1), until they are
  // narrowed into the topology's RunStarts.
  FilledVector<SimplexId> edge_runs, triangle_runs, tet_runs;

  Tuple Unbucket(const Bucketed& e, SimplexId stretch_vertex_begin) const {
    if (e[0] == kWhole) return bucketed_wholes[e[3]][size_t(e[1]) | size_t(e[2]) << 16];
    const SimplexId a = stretch_vertex_begin + e[0];
    return {a, a + e[1], a + e[2], a + e[3]};
  }
  SimplexId InternalVertex(int64_t tet, int k) const {
    return t.vertex_internal_id_[mesh.tetrahedra[4 * size_t(tet) + k]];
  }

  absl::Status SortVertices();
  void BucketTetrahedra();
  void SortTetrahedra();
  // Stretch k's vertices: [first, second).
  std::pair<SimplexId, SimplexId> StretchVertices(int64_t k) const {
    return {SimplexId(k * stretch_vertices),
            SimplexId(std::min<int64_t>(nv, (k + 1) * stretch_vertices))};
  }
  void FindExternalTetrahedra();
  void FindBlockNeighbors();
  void ReserveFaces();
  void ComputeWindowFaces(int32_t window, int32_t window_size);
  void ComputeBlockFaces(int32_t b, Scratch& sc, BlockFaces& out);
  void CollectStars(int32_t b, Scratch& sc) const;
  void CollectUpperFaces(SimplexId v, SimplexId star_from, SimplexId star_to, Scratch& sc) const;
  static void EmitVertexFaces(SimplexId v, const Scratch& sc, BlockFaces& out);
  absl::Status AppendWindowFaces(int32_t window, int32_t window_size);
  void BuildRunLookups();
  void ListBlockNeighbors();
  // The edges and triangles: ReserveFaces to BuildRunLookups, progress `phase` going from
  // `from` to `to`; sets has_faces_ when done. On a stop the caller clears what was built.
  absl::Status BuildFaces(const Progress& progress, std::string_view phase, double from, double to);
};

// Renumbers the vertices block by block; leaves the permutations and vertex_block_ for the tets.
absl::Status Topology::Encoder::SortVertices() {
  // Vertices: stable counting sort by block.
  std::vector<SimplexId> block_count(num_blocks, 0);
  for (SimplexId v = 0; v < nv; ++v) ++block_count[vertex_block[v]];
  for (int32_t b = 0; b < num_blocks; ++b) {
    if (block_count[b] == 0) {
      return absl::InvalidArgumentError(absl::StrCat("blocks: block ", b, " has no vertex"));
    }
  }
  t.block_vertex_begin_ = PrefixSum(block_count);
  t.vertex_input_id_.resize(nv);
  t.vertex_internal_id_.resize(nv);
  t.vertex_block_.resize(nv);
  std::vector<SimplexId> cursor(t.block_vertex_begin_.begin(), t.block_vertex_begin_.end() - 1);
  for (SimplexId v = 0; v < nv; ++v) {
    const SimplexId id = cursor[vertex_block[v]]++;
    t.vertex_internal_id_[v] = id;
    t.vertex_input_id_[id] = v;
    t.vertex_block_[id] = vertex_block[v];
  }
  return absl::OkStatus();
}

// Buckets the tetrahedra by the stretch of their lowest vertex; leaves stretch_tet_begin,
// tet_input_id_ and each tetrahedron's sorted internal tuple at its place in `bucketed`.
void Topology::Encoder::BucketTetrahedra() {
  // The tuples are written as the tetrahedra are placed, while the mesh is read in order: the
  // sort within each stretch then reads its own tuples, not the mesh's at scattered places. They
  // take 8 bytes, half of the mesh's 16, so as the mesh is handed back the resident total falls
  // (with 16 bytes, the rise set a critical points job's peak on a mesh whose cells come in no
  // spatial order). Each corner goes with its input position through the sorting network
  // (4 * vertex + position), so the corners' order comes for free.
  stretch_vertices = SimplexId(
      std::clamp<int64_t>(int64_t(nv) * kStretchTets / std::max(nt, 1), 1, kMaxStretchVertices));
  const int32_t stretches = int32_t((int64_t(nv) + stretch_vertices - 1) / stretch_vertices);
  bucketed.resize(size_t(nt));
  bucketed_wholes.assign(size_t(std::max(threads, 1)), {});
  std::vector<uint8_t>* corners = options.input_corners;
  if (corners != nullptr) corners->resize(size_t(nt));
  BucketItems(
      nt, stretches, threads,
      [&](int64_t i, auto&& emit) {
        emit(int32_t(std::min(std::min(InternalVertex(i, 0), InternalVertex(i, 1)),
                              std::min(InternalVertex(i, 2), InternalVertex(i, 3))) /
                     stretch_vertices));
      },
      stretch_tet_begin, t.tet_input_id_,
      [&](int64_t i, SimplexId slot, int chunk) {
        int64_t c[4];
        for (int k = 0; k < 4; ++k) c[k] = int64_t(InternalVertex(i, k)) << 2 | k;
        const auto order = [&c](int a, int b) {
          if (c[b] < c[a]) std::swap(c[a], c[b]);
        };
        order(0, 1), order(2, 3), order(0, 2), order(1, 3), order(1, 2);
        Tuple s;
        uint8_t byte = 0;
        for (int k = 0; k < 4; ++k) {
          s[k] = SimplexId(c[k] >> 2);
          byte |= uint8_t((c[k] & 3) << (2 * k));
        }
        if (corners != nullptr) (*corners)[size_t(slot)] = byte;
        const SimplexId offset = s[0] % stretch_vertices;
        if (s[3] - s[0] < kWhole) {
          bucketed[slot] = {uint16_t(offset), uint16_t(s[1] - s[0]), uint16_t(s[2] - s[0]),
                            uint16_t(s[3] - s[0])};
          return;
        }
        std::vector<Tuple>& wholes = bucketed_wholes[chunk];
        bucketed[slot] = {kWhole, uint16_t(wholes.size()), uint16_t(wholes.size() >> 16),
                          uint16_t(chunk)};
        wholes.push_back(s);
      },
      [&](int64_t from, int64_t to) {
        if (!options.release_tetrahedra) return;
        ReleasePages(mesh.tetrahedra.data() + 4 * size_t(from),
                     mesh.tetrahedra.data() + 4 * size_t(to));
      });
}

// Orders each stretch's tetrahedra by lowest vertex (a stable counting sort of the stretch's own
// tuples), so a vertex's star is a few nearby runs, however the file ordered its cells, and
// encodes them (NarrowTetrahedra), handing each stretch's tuples back once sorted (one madvise
// per stretch of about 64k tetrahedra: one per block would cost more than the sort, in TLB
// shootdowns). Blocks are runs of vertices, so their tetrahedra come out grouped too.
void Topology::Encoder::SortTetrahedra() {
  const int64_t stretches = int64_t(stretch_tet_begin.size()) - 1;
  // First where each vertex's run starts (a count of lowest vertices per stretch), which gives
  // the encoding its bases: the lowest vertex of each group's first tetrahedron.
  tet_runs.resize(size_t(nv) + 1);  // every entry is written below
  tet_runs[nv] = nt;
  ParallelFor(stretches, threads, [&](int64_t k, int) {
    const auto [vbegin, vend] = StretchVertices(k);
    const SimplexId begin = stretch_tet_begin[k], end = stretch_tet_begin[k + 1];
    SimplexId* run = &tet_runs[vbegin];
    std::fill(run, run + (vend - vbegin), 0);
    for (SimplexId i = begin; i < end; ++i) ++run[Unbucket(bucketed[i], vbegin)[0] - vbegin];
    SimplexId at = begin;
    for (SimplexId v = 0; v < vend - vbegin; ++v) at += std::exchange(run[v], at);
  });
  t.block_tet_begin_.resize(size_t(num_blocks) + 1);
  for (int32_t b = 0; b <= num_blocks; ++b) {
    t.block_tet_begin_[b] = tet_runs[t.block_vertex_begin_[b]];
  }
  t.tets_.Start(nt, [&](SimplexId first) {
    const auto after = std::upper_bound(tet_runs.begin(), tet_runs.end(), first);
    return SimplexId(after - tet_runs.begin() - 1);
  });
  // Then each stretch's tetrahedra placed and encoded, with their input ids and corners.
  std::vector<StretchTets> scratch_tets(std::max(threads, 1));
  std::vector<std::vector<Tuple>> stretch_wholes(static_cast<size_t>(stretches));
  std::vector<uint8_t>* corners = options.input_corners;
  ParallelFor(stretches, threads, [&](int64_t k, int thread) {
    StretchTets& sc = scratch_tets[thread];
    const auto [vbegin, vend] = StretchVertices(k);
    const SimplexId begin = stretch_tet_begin[k], end = stretch_tet_begin[k + 1];
    sc.at.assign(tet_runs.begin() + vbegin, tet_runs.begin() + vend);
    sc.inputs.assign(t.tet_input_id_.begin() + begin, t.tet_input_id_.begin() + end);
    if (corners != nullptr) sc.corners.assign(corners->begin() + begin, corners->begin() + end);
    sc.wholes.clear();
    for (SimplexId i = 0; i < end - begin; ++i) {
      const Tuple s = Unbucket(bucketed[begin + i], vbegin);
      const SimplexId to = sc.at[s[0] - vbegin]++;
      if (!t.tets_.Put(to, s.data())) sc.wholes.push_back({to, s});
      t.tet_input_id_[to] = sc.inputs[i];
      if (corners != nullptr) (*corners)[to] = sc.corners[i];
    }
    std::sort(sc.wholes.begin(), sc.wholes.end(),
              [](const auto& x, const auto& y) { return x.first < y.first; });
    for (const auto& [id, tuple] : sc.wholes) stretch_wholes[k].push_back(tuple);
    // Only this stretch reads its tuples (pages it shares with the next stay).
    ReleasePages(bucketed.data() + begin, bucketed.data() + end);
  });
  bucketed = {};
  bucketed_wholes = {};
  stretch_tet_begin = {};
  // The wholes in id order: the stretches' ids ascend with them.
  std::vector<Tuple> wholes;
  size_t total = 0;
  for (const auto& w : stretch_wholes) total += w.size();
  wholes.reserve(total);
  for (auto& w : stretch_wholes) {
    wholes.insert(wholes.end(), w.begin(), w.end());
    w = {};
  }
  t.tets_.Finish(std::move(wholes), threads);
  t.vertex_tet_begin_.Assign(tet_runs, threads);
  tet_runs = {};
}

// Lists each block's external tetrahedra; with its internal ones they make its vertices' stars.
void Topology::Encoder::FindExternalTetrahedra() {
  // External tetrahedra: a tetrahedron is external to every later block holding one of its
  // vertices. Its sorted vertices have non-decreasing blocks, so distinct blocks are adjacent.
  auto for_each_external_block = [&](SimplexId tet, auto&& fn) {
    const auto s = t.tetrahedron(tet);
    int32_t last = t.vertex_block_[s[0]];
    for (int k = 1; k < 4; ++k) {
      const int32_t b = t.vertex_block_[s[k]];
      if (b != last) {
        fn(b);
        last = b;
      }
    }
  };
  std::vector<SimplexId> offsets, external;
  BucketItems(
      nt, num_blocks, threads, for_each_external_block, offsets, external,
      [](int64_t, SimplexId, int) {}, [](int64_t, int64_t) {});
  t.external_tets_.Assign(offsets, external, threads);
}

// Allocates the window buffers and reserves the face arrays; leaves them empty for the windows.
void Topology::Encoder::ReserveFaces() {
  // Blocks go in windows: each window is computed in parallel, then appended in block order to
  // the final arrays, whose upper bounds (6 edges and 4 triangles per tetrahedron) are reserved
  // but untouched, so memory grows by what is written and no second copy of the faces exists.
  faces.resize(std::min(num_blocks, kWindow));
  scratch.resize(std::max(threads, 1));
  t.edge_upper_.Reserve(6 * size_t(nt));
  triangle_runs.reserve(6 * size_t(nt) + 1);
  t.triangle_third_.Reserve(4 * size_t(nt));
  t.triangle_boundary_.reserve((4 * size_t(nt) + 63) / 64);
  edge_runs.resize(nv + 1);  // every entry is written by AppendWindowFaces
}

// Computes the faces of the window's blocks in parallel; leaves them in `faces` to be appended.
void Topology::Encoder::ComputeWindowFaces(int32_t window, int32_t window_size) {
  ParallelFor(window_size, threads, [&](int64_t index, int thread) {
    ComputeBlockFaces(window + static_cast<int32_t>(index), scratch[thread], faces[index]);
  });
}

// Block b's edges, triangles and boundary flags into `out`.
void Topology::Encoder::ComputeBlockFaces(int32_t b, Scratch& sc, BlockFaces& out) {
  // Per internal vertex v (ascending), from its star: the vertices above v give its edges, the
  // pairs above v in each tetrahedron its triangles, each seen once per incident tetrahedron (so a
  // run of one is a boundary triangle). Only small per-vertex lists are sorted.
  const SimplexId vbegin = t.block_vertex_begin_[b], vend = t.block_vertex_begin_[b + 1];
  out.edges.clear();
  out.edge_triangles.clear();
  out.triangle_third.clear();
  out.triangle_boundary.clear();
  out.crowded = false;
  out.whole_uppers = out.whole_thirds = 0;
  CollectStars(b, sc);
  SimplexId star_from = 0;
  for (SimplexId v = vbegin; v < vend; ++v) {
    const SimplexId star_to = sc.star_begin[v - vbegin];
    CollectUpperFaces(v, star_from, star_to, sc);
    star_from = star_to;
    EmitVertexFaces(v, sc, out);
  }
}

// Each block's neighbours (the other blocks of its vertices' stars), sorted, in neighbors[b].
void Topology::Encoder::FindBlockNeighbors() {
  // Two blocks are neighbours when a tetrahedron holds a vertex of each, and a tetrahedron is
  // external to every block of its vertices but its lowest's. So each block's external
  // tetrahedra name all its neighbours but the later blocks it reaches only through its own
  // tetrahedra, and those blocks find it among theirs: the external lists (about a tenth of
  // the tetrahedra) and their transpose give every pair.
  neighbors.resize(num_blocks);
  std::vector<std::vector<int32_t>> met(std::max(threads, 1));  // per thread, the last b per block
  ParallelFor(num_blocks, threads, [&](int64_t b, int thread) {
    std::vector<int32_t>& adjacent = neighbors[b];
    std::vector<int32_t>& mark = met[thread];
    if (mark.empty()) mark.assign(num_blocks, -1);
    mark[b] = int32_t(b);
    for (SimplexId tet : t.external_tetrahedra(int32_t(b))) {
      const auto s = t.tetrahedron(tet);
      for (int k = 0; k < 4; ++k) {
        const int32_t nb = t.vertex_block_[s[k]];
        if (mark[nb] != b) {
          mark[nb] = int32_t(b);
          adjacent.push_back(nb);
        }
      }
    }
  });
  // The transpose: c, a neighbour of b found by b, has b as a neighbour. Blocks later than c
  // are the ones c may not have found; earlier ones it did.
  for (int32_t b = 0; b < num_blocks; ++b) {
    const size_t found = neighbors[b].size();
    for (size_t i = 0; i < found; ++i) {
      const int32_t c = neighbors[b][i];
      if (c < b) neighbors[c].push_back(b);
    }
  }
  ParallelFor(num_blocks, threads, [&](int64_t b, int) {
    std::vector<int32_t>& adjacent = neighbors[b];
    std::sort(adjacent.begin(), adjacent.end());
    adjacent.erase(std::unique(adjacent.begin(), adjacent.end()), adjacent.end());
    adjacent.shrink_to_fit();
  });
}

// Block b's tetrahedra (external, then internal) decoded once into `tuples`, and its vertex stars
// as CSR of positions in it; leaves star_begin[i] at the end of star i.
void Topology::Encoder::CollectStars(int32_t b, Scratch& sc) const {
  const SimplexId vbegin = t.block_vertex_begin_[b], vend = t.block_vertex_begin_[b + 1];
  const auto external = t.external_tetrahedra(b);
  const SimplexId tet_begin = t.block_tet_begin_[b], tet_end = t.block_tet_begin_[b + 1];
  sc.tuples.clear();
  for (SimplexId tet : external) sc.tuples.push_back(t.tetrahedron(tet));
  for (SimplexId tet = tet_begin; tet < tet_end; ++tet) sc.tuples.push_back(t.tetrahedron(tet));
  // Stars of the internal vertices (CSR, counting sort).
  sc.star_begin.assign(size_t(vend - vbegin) + 1, 0);
  for (const Tuple& s : sc.tuples) {
    for (int k = 0; k < 4; ++k) {
      if (s[k] >= vbegin && s[k] < vend) ++sc.star_begin[s[k] - vbegin + 1];
    }
  }
  for (size_t i = 1; i < sc.star_begin.size(); ++i) sc.star_begin[i] += sc.star_begin[i - 1];
  sc.star.resize(sc.star_begin.back());
  for (size_t i = 0; i < sc.tuples.size(); ++i) {
    const Tuple& s = sc.tuples[i];
    for (int k = 0; k < 4; ++k) {
      if (s[k] >= vbegin && s[k] < vend) sc.star[sc.star_begin[s[k] - vbegin]++] = SimplexId(i);
    }
  }
}

// The vertices and pairs above v in its star, sorted, with pair counts, for EmitVertexFaces.
void Topology::Encoder::CollectUpperFaces(SimplexId v, SimplexId star_from, SimplexId star_to,
                                          Scratch& sc) const {
  // Each upper vertex and pair comes once per tetrahedron around it (about 30 and 20 times for
  // 7 and 12 distinct ones on wavelet meshes): they are counted in a small open-addressing table,
  // then the few distinct ones sorted. An upper vertex w is the key (w << 32) | w, a pair (b, c)
  // with b < c is (b << 32) | c: they never meet.
  constexpr uint64_t kNoKey = ~uint64_t(0);
  const int bits = std::max(4, int(std::bit_width(12 * size_t(star_to - star_from))));  // half free
  const uint64_t mask = (uint64_t(1) << bits) - 1;
  if (sc.slot_key.size() <= mask) {
    sc.slot_key.assign(mask + 1, kNoKey);
    sc.slot_count.assign(mask + 1, 0);
  }
  const auto count = [&](uint64_t key) __attribute__((always_inline)) {
    uint64_t h = (key * 0x9e3779b97f4a7c15u) >> (64 - bits);
    while (sc.slot_key[h] != key) {
      if (sc.slot_key[h] == kNoKey) {
        sc.slot_key[h] = key;
        sc.used.push_back(uint32_t(h));
        break;
      }
      h = (h + 1) & mask;
    }
    ++sc.slot_count[h];
  };
  for (SimplexId i = star_from; i < star_to; ++i) {
    const Tuple& s = sc.tuples[sc.star[i]];
    int p = 0;
    while (s[p] != v) ++p;
    for (int j = p + 1; j < 4; ++j) {
      const uint64_t high = uint64_t(uint32_t(s[j])) << 32;
      count(high | uint32_t(s[j]));
      for (int k = j + 1; k < 4; ++k) count(high | uint32_t(s[k]));
    }
  }
  sc.upper.clear();
  sc.pairs.clear();
  for (uint32_t h : sc.used) {
    const uint64_t key = sc.slot_key[h];
    if (key >> 32 == (key & 0xffffffffu)) {
      sc.upper.push_back(SimplexId(key >> 32));
    } else {
      sc.pairs.push_back({key, sc.slot_count[h]});
    }
    sc.slot_key[h] = kNoKey;
    sc.slot_count[h] = 0;
  }
  sc.used.clear();
  std::sort(sc.upper.begin(), sc.upper.end());
  std::sort(sc.pairs.begin(), sc.pairs.end(),
            [](const Scratch::Pair& a, const Scratch::Pair& b) { return a.key < b.key; });
}

// Appends v's edges and triangles to the block's runs in `out`; the next vertex's follow them.
void Topology::Encoder::EmitVertexFaces(SimplexId v, const Scratch& sc, BlockFaces& out) {
  const size_t first_edge = out.edges.size();
  for (SimplexId w : sc.upper) {
    out.edges.push_back(uint64_t(uint32_t(v)) << 32 | uint32_t(w));
    out.whole_uppers += !NarrowIds::Fits(w, v);
  }
  out.edge_triangles.resize(out.edges.size(), 0);
  // Pairs (b, c) sorted by b; upper is sorted and holds every b: walk both.
  size_t edge = first_edge;
  for (const Scratch::Pair& pair : sc.pairs) {
    const uint32_t b = uint32_t(pair.key >> 32);
    while (uint32_t(out.edges[edge]) != b) ++edge;
    ++out.edge_triangles[edge];
    out.triangle_third.push_back(SimplexId(pair.key & 0xffffffffu));
    out.whole_thirds += !NarrowIds::Fits(out.triangle_third.back(), v);
    out.triangle_boundary.push_back(pair.count == 1);
    out.crowded |= pair.count > 2;
  }
}

// Appends the window's faces to the final arrays, run starts included.
absl::Status Topology::Encoder::AppendWindowFaces(int32_t window, int32_t window_size) {
  // Offsets in block order, then every block written in parallel: its edges, the run starts of
  // its own vertices and edges (absolute, so no pass over all of them follows) and its boundary
  // bits; only the words it shares with the blocks beside it are or-ed in atomically.
  std::vector<size_t> edge_at(window_size + 1), triangle_at(window_size + 1);
  std::vector<size_t> upper_at(window_size + 1), third_at(window_size + 1);  // whole slots
  edge_at[0] = t.edge_upper_.size();
  triangle_at[0] = t.triangle_third_.size();
  upper_at[0] = t.edge_upper_.wholes();
  third_at[0] = t.triangle_third_.wholes();
  for (int32_t index = 0; index < window_size; ++index) {
    edge_at[index + 1] = edge_at[index] + faces[index].edges.size();
    triangle_at[index + 1] = triangle_at[index] + faces[index].triangle_third.size();
    upper_at[index + 1] = upper_at[index] + faces[index].whole_uppers;
    third_at[index + 1] = third_at[index] + faces[index].whole_thirds;
    t.crowded_triangles_ |= faces[index].crowded;
  }
  // Ids are 32-bit (SimplexId), run starts included.
  if (triangle_at[window_size] > size_t(INT32_MAX)) {
    return absl::ResourceExhaustedError(absl::StrCat("mesh: more than ", triangle_at[window_size],
                                                     " triangles exceed the 32-bit id range"));
  }
  // Within the reservations of ReserveFaces: no reallocation.
  t.edge_upper_.Resize(edge_at[window_size], upper_at[window_size]);
  triangle_runs.resize(edge_at[window_size]);
  t.triangle_third_.Resize(triangle_at[window_size], third_at[window_size]);
  t.triangle_boundary_.resize((triangle_at[window_size] + 63) / 64, 0);
  ParallelFor(window_size, threads, [&](int64_t index, int) {
    const BlockFaces& bf = faces[index];
    const int32_t b = window + int32_t(index);
    size_t edge = edge_at[index], triangle = triangle_at[index];
    size_t upper_slot = upper_at[index], third_slot = third_at[index];
    size_t i = 0;  // bf's edge
    for (SimplexId v = t.block_vertex_begin_[b]; v < t.block_vertex_begin_[b + 1]; ++v) {
      edge_runs[v] = SimplexId(edge);
      const size_t first_triangle = triangle;
      for (; i < bf.edges.size() && SimplexId(bf.edges[i] >> 32) == v; ++i, ++edge) {
        t.edge_upper_.Set(edge, SimplexId(bf.edges[i] & 0xffffffffu), v, upper_slot);
        triangle_runs[edge] = SimplexId(triangle);
        triangle += bf.edge_triangles[i];
      }
      for (size_t f = first_triangle; f < triangle; ++f) {
        t.triangle_third_.Set(f, bf.triangle_third[f - triangle_at[index]], v, third_slot);
      }
    }
    // Boundary bits a word at a time; the first and last words may hold other blocks' bits.
    const size_t first = triangle_at[index], end = triangle_at[index + 1];
    uint64_t word = 0;
    const auto flush = [&](size_t w) {
      if (word == 0) return;
      if (w * 64 >= first && w * 64 + 64 <= end) {
        t.triangle_boundary_[w] = word;
      } else {
        std::atomic_ref<uint64_t>(t.triangle_boundary_[w])
            .fetch_or(word, std::memory_order_relaxed);
      }
      word = 0;
    };
    for (size_t f = first; f < end; ++f) {
      if (f % 64 == 0 && f != first) flush(f / 64 - 1);
      word |= uint64_t(bf.triangle_boundary[f - first]) << (f % 64);
    }
    if (end > first) flush((end - 1) / 64);
  });
  return absl::OkStatus();
}

// Builds the edge -> vertex and triangle -> edge lookups and finishes the narrow runs and their
// starts.
void Topology::Encoder::BuildRunLookups() {
  // Not num_edges() and num_triangles(): they say 0 until has_faces_ is set.
  t.edge_lowest_.Build(edge_runs, SimplexId(t.edge_upper_.size()), threads);
  t.triangle_edge_.Build(triangle_runs, SimplexId(t.triangle_third_.size()), threads);
  t.edge_upper_.Finish(threads);
  t.triangle_third_.Finish(threads);
  t.vertex_edge_begin_.Assign(edge_runs, threads);
  t.edge_triangle_begin_.Assign(triangle_runs, threads);
  edge_runs = {};
  triangle_runs = {};
}

// Concatenates the per-block neighbour lists into the block adjacency, the topology's last part.
void Topology::Encoder::ListBlockNeighbors() {
  t.block_neighbor_offsets_.assign(num_blocks + 1, 0);
  for (int32_t b = 0; b < num_blocks; ++b) {
    t.block_neighbor_offsets_[b + 1] =
        t.block_neighbor_offsets_[b] + static_cast<int32_t>(neighbors[b].size());
  }
  t.block_neighbors_.reserve(t.block_neighbor_offsets_.back());
  for (const auto& n : neighbors) {
    t.block_neighbors_.insert(t.block_neighbors_.end(), n.begin(), n.end());
  }
}

// The "encode" phase as the Encoder's steps, with its progress reports and stops between them.
absl::StatusOr<std::shared_ptr<const Topology>> Topology::Build(
    const Mesh& mesh, std::span<const int32_t> vertex_block, const TopologyOptions& options,
    const Progress& progress) {
  // Without points (a caller may have freed them) the vertex count comes from the blocks.
  const SimplexId nv = mesh.points.empty() ? SimplexId(vertex_block.size()) : mesh.num_vertices();
  const SimplexId nt = mesh.num_tetrahedra();
  const int threads = options.threads > 0 ? options.threads : DefaultThreads();
  ASSIGN_OR_RETURN(const int32_t num_blocks, CountBlocks(vertex_block, nv));

  RETURN_IF_ERROR(progress.Update(kPhase, 0));
  auto topo = std::shared_ptr<Topology>(new Topology());
  Topology& t = *topo;
  t.num_vertices_ = nv;
  t.num_blocks_ = num_blocks;
  Encoder encoder{mesh, vertex_block, nv, nt, num_blocks, threads, t, options};
  const auto step = [&](const char* name) { return Trace::Scope(options.trace, name, "encode"); };
  {
    auto span = step("sort vertices");
    RETURN_IF_ERROR(encoder.SortVertices());
  }
  // Tetrahedra: stable bucket sort by the stretch of vertices (about 64k tetrahedra) holding the
  // lowest vertex, each sorted internal tuple written straight to its place in 8 bytes, then
  // within each stretch by the lowest vertex, encoded in 8 bytes as they are placed. Each step
  // hands back what it has read as it goes (the mesh's tetrahedra when release_tetrahedra, then
  // the bucketed tuples), so no two copies are resident in full. (Not one bucket sort by lowest
  // vertex straight into the encoding: its writes would scatter over every page at once, raising
  // the peak on a mesh whose cells come in no spatial order. Each bucket being written keeps one
  // page partly filled per thread and array, so the buckets are few: stretches, not blocks,
  // whose thousands of partial pages set the encoding's peak.)
  {
    auto span = step("bucket tetrahedra");
    encoder.BucketTetrahedra();
  }
  {
    auto span = step("sort tetrahedra");
    encoder.SortTetrahedra();
  }
  if (options.tetrahedra_read) options.tetrahedra_read(t);
  RETURN_IF_ERROR(progress.Update(kPhase, 0.15));

  {
    auto span = step("external tetrahedra");
    encoder.FindExternalTetrahedra();
  }
  {
    auto span = step("block neighbors");
    encoder.FindBlockNeighbors();
    encoder.ListBlockNeighbors();
  }
  if (options.faces) {
    auto span = step("faces");
    // Edges and triangles are about three quarters of the time.
    RETURN_IF_ERROR(encoder.BuildFaces(progress, kPhase, 0.2, 1));
  }
  RETURN_IF_ERROR(progress.Update(kPhase, 1));
  return topo;
}

absl::Status Topology::Encoder::BuildFaces(const Progress& progress, std::string_view phase,
                                           double from, double to) {
  ReserveFaces();
  const double span = to - from;
  for (int32_t window = 0; window < num_blocks; window += kWindow) {
    RETURN_IF_ERROR(progress.Update(phase, from + 0.95 * span * window / num_blocks));
    const int32_t window_size = std::min(kWindow, num_blocks - window);
    ComputeWindowFaces(window, window_size);
    RETURN_IF_ERROR(AppendWindowFaces(window, window_size));
  }
  faces.clear();  // the last window's, now appended
  // The ends of the last runs.
  edge_runs[nv] = SimplexId(t.edge_upper_.size());
  triangle_runs.push_back(SimplexId(t.triangle_third_.size()));
  RETURN_IF_ERROR(progress.Update(phase, from + 0.95 * span));
  BuildRunLookups();
  t.has_faces_.store(true, std::memory_order_release);
  return absl::OkStatus();
}

absl::Status Topology::EnsureFaces(const Progress& progress, const FacesOptions& options) const {
  if (has_faces()) return absl::OkStatus();
  MutexLock lock(faces_mu_);
  if (has_faces()) return absl::OkStatus();  // built while this call waited
  auto span = Trace::Scope(options.trace, "faces", "encode");
  // Every topology is made by Build (new Topology, never a const object), and what this writes
  // no reader reads before has_faces_ says it is there (see has_faces_).
  Topology& t = const_cast<Topology&>(*this);
  static const Mesh kNoMesh{};  // the face steps read the topology's own tetrahedra only
  const TopologyOptions encoding{.faces = true};
  const int threads = options.threads > 0 ? options.threads : DefaultThreads();
  Encoder encoder{kNoMesh, {}, num_vertices_, num_tetrahedra(), num_blocks_, threads, t, encoding};
  RETURN_IF_ERROR(progress.Update("faces", 0));
  if (absl::Status built = encoder.BuildFaces(progress, "faces", 0, 1); !built.ok()) {
    t.ClearFaces();
    return built;
  }
  // Built and kept: a stop asked for from now on is the caller's to notice.
  progress.Update("faces", 1).IgnoreError();
  return absl::OkStatus();
}

void Topology::ClearFaces() {
  vertex_edge_begin_ = {};
  edge_upper_ = {};
  edge_lowest_ = {};
  edge_triangle_begin_ = {};
  triangle_third_ = {};
  triangle_edge_ = {};
  triangle_boundary_ = {};
  crowded_triangles_ = false;
}

}  // namespace actopo
