#include "server/core/topology.h"

#include <algorithm>
#include <array>

#include "absl/strings/str_cat.h"
#include "server/core/parallel.h"

namespace actopo {
namespace {

// Bytes in use: the face arrays keep an untouched upper-bound reservation (see Build), which
// costs address space, not memory.
template <class T>
int64_t VectorBytes(const std::vector<T>& v) {
  return static_cast<int64_t>(v.size() * sizeof(T));
}

// Edges and triangles owned by one block (lowest vertex inside it), sorted and unique, with the
// number of tetrahedra around each triangle (1 = boundary).
struct BlockFaces {
  std::vector<uint64_t> edges;  // (a << 32) | b
  std::vector<std::array<SimplexId, 3>> triangles;
  std::vector<uint8_t> triangle_boundary;
};

// Offsets of per-item counts: out[0] = 0, out[i + 1] = out[i] + counts[i].
template <class T>
std::vector<T> PrefixSum(const std::vector<T>& counts) {
  std::vector<T> out(counts.size() + 1, 0);
  for (size_t i = 0; i < counts.size(); ++i) out[i + 1] = out[i] + counts[i];
  return out;
}

}  // namespace

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
    case 1: return vertex_block_[edge_vertices_[2 * size_t(s)]];
    case 2: return vertex_block_[triangle_vertices_[3 * size_t(s)]];
    default: return vertex_block_[tet_vertices_[4 * size_t(s)]];
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
  // Edges starting at a are few (tens) and sorted by their second vertex.
  SimplexId lo = vertex_edge_begin_[a], hi = vertex_edge_begin_[a + 1];
  while (lo < hi) {
    const SimplexId mid = lo + (hi - lo) / 2;
    if (edge_vertices_[2 * size_t(mid) + 1] < b) {
      lo = mid + 1;
    } else {
      hi = mid;
    }
  }
  return lo < vertex_edge_begin_[a + 1] && edge_vertices_[2 * size_t(lo) + 1] == b ? lo : -1;
}

SimplexId Topology::FindTriangle(SimplexId a, SimplexId b, SimplexId c) const {
  SimplexId lo = vertex_triangle_begin_[a], hi = vertex_triangle_begin_[a + 1];
  const SimplexId end = hi;
  while (lo < hi) {
    const SimplexId mid = lo + (hi - lo) / 2;
    const SimplexId* t = &triangle_vertices_[3 * size_t(mid)];
    if (t[1] < b || (t[1] == b && t[2] < c)) {
      lo = mid + 1;
    } else {
      hi = mid;
    }
  }
  if (lo == end) return -1;
  const SimplexId* t = &triangle_vertices_[3 * size_t(lo)];
  return t[1] == b && t[2] == c ? lo : -1;
}

TopologyBytes Topology::bytes() const {
  TopologyBytes b;
  b.vertices = VectorBytes(vertex_block_) + VectorBytes(vertex_input_id_) +
               VectorBytes(vertex_internal_id_);
  b.edges = VectorBytes(edge_vertices_) + VectorBytes(vertex_edge_begin_);
  b.triangles = VectorBytes(triangle_vertices_) + VectorBytes(vertex_triangle_begin_) +
                VectorBytes(triangle_boundary_);
  b.tetrahedra = VectorBytes(tet_vertices_) + VectorBytes(tet_input_id_) +
                 VectorBytes(tet_internal_id_);
  b.blocks = VectorBytes(block_vertex_begin_) + VectorBytes(block_tet_begin_) +
             VectorBytes(external_offsets_) + VectorBytes(external_tets_) +
             VectorBytes(block_neighbor_offsets_) + VectorBytes(block_neighbors_);
  return b;
}

absl::StatusOr<std::shared_ptr<const Topology>> Topology::Build(
    const Mesh& mesh, std::span<const int32_t> vertex_block, const TopologyOptions& options) {
  const SimplexId nv = mesh.num_vertices();
  const SimplexId nt = mesh.num_tetrahedra();
  const int threads = options.threads > 0 ? options.threads : DefaultThreads();
  if (vertex_block.size() != static_cast<size_t>(nv)) {
    return absl::InvalidArgumentError(absl::StrCat("blocks: ", vertex_block.size(),
                                                   " block ids for ", nv, " vertices"));
  }
  int32_t num_blocks = 0;
  for (SimplexId v = 0; v < nv; ++v) {
    if (vertex_block[v] < 0 || vertex_block[v] >= nv) {
      return absl::InvalidArgumentError(
          absl::StrCat("blocks: vertex ", v, " has block id ", vertex_block[v]));
    }
    num_blocks = std::max(num_blocks, vertex_block[v] + 1);
  }

  auto topo = std::shared_ptr<Topology>(new Topology());
  Topology& t = *topo;
  t.num_vertices_ = nv;
  t.num_blocks_ = num_blocks;

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
  {
    std::vector<SimplexId> cursor(t.block_vertex_begin_.begin(), t.block_vertex_begin_.end() - 1);
    for (SimplexId v = 0; v < nv; ++v) {
      const SimplexId id = cursor[vertex_block[v]]++;
      t.vertex_internal_id_[v] = id;
      t.vertex_input_id_[id] = v;
      t.vertex_block_[id] = vertex_block[v];
    }
  }

  // Tetrahedra: stable counting sort by the block of the lowest vertex, then each sorted internal
  // tuple written straight to its place (no second copy of the tetrahedra at any time).
  {
    const auto internal = [&](int64_t i, int k) {
      return t.vertex_internal_id_[mesh.tetrahedra[4 * size_t(i) + k]];
    };
    const auto lowest_block = [&](int64_t i) {
      return t.vertex_block_[std::min(std::min(internal(i, 0), internal(i, 1)),
                                      std::min(internal(i, 2), internal(i, 3)))];
    };
    std::fill(block_count.begin(), block_count.end(), 0);
    for (SimplexId i = 0; i < nt; ++i) ++block_count[lowest_block(i)];
    t.block_tet_begin_ = PrefixSum(block_count);
    std::vector<SimplexId> cursor(t.block_tet_begin_.begin(), t.block_tet_begin_.end() - 1);
    t.tet_input_id_.resize(nt);
    t.tet_internal_id_.resize(nt);
    for (SimplexId i = 0; i < nt; ++i) {
      const SimplexId id = cursor[lowest_block(i)]++;
      t.tet_input_id_[id] = i;
      t.tet_internal_id_[i] = id;
    }
    t.tet_vertices_.resize(4 * size_t(nt));
    constexpr int64_t kTetsPerTask = 1 << 16;
    ParallelFor((int64_t(nt) + kTetsPerTask - 1) / kTetsPerTask, threads, [&](int64_t task, int) {
      const int64_t end = std::min<int64_t>(nt, (task + 1) * kTetsPerTask);
      for (int64_t id = task * kTetsPerTask; id < end; ++id) {
        SimplexId* s = &t.tet_vertices_[4 * size_t(id)];
        for (int k = 0; k < 4; ++k) s[k] = internal(t.tet_input_id_[id], k);
        SortVertexIds(s, 4);
      }
    });
  }

  // External tetrahedra: a tetrahedron is external to every later block holding one of its
  // vertices. Its sorted vertices have non-decreasing blocks, so distinct blocks are adjacent.
  {
    auto for_each_external_block = [&](SimplexId tet, auto&& fn) {
      const SimplexId* s = &t.tet_vertices_[4 * size_t(tet)];
      int32_t last = t.vertex_block_[s[0]];
      for (int k = 1; k < 4; ++k) {
        const int32_t b = t.vertex_block_[s[k]];
        if (b != last) {
          fn(b);
          last = b;
        }
      }
    };
    std::fill(block_count.begin(), block_count.end(), 0);
    for (SimplexId i = 0; i < nt; ++i) {
      for_each_external_block(i, [&](int32_t b) { ++block_count[b]; });
    }
    t.external_offsets_ = PrefixSum(block_count);
    t.external_tets_.resize(t.external_offsets_.back());
    std::vector<SimplexId> cursor(t.external_offsets_.begin(), t.external_offsets_.end() - 1);
    for (SimplexId i = 0; i < nt; ++i) {
      for_each_external_block(i, [&](int32_t b) { t.external_tets_[cursor[b]++] = i; });
    }
  }

  // Edges, triangles and boundary flags, block-parallel, then concatenated in block order. Per
  // internal vertex v (ascending), from its star: the vertices above v give its edges, the pairs
  // above v in each tetrahedron its triangles, each seen once per incident tetrahedron (so a run
  // of one is a boundary triangle). Only small per-vertex lists are sorted.
  struct Scratch {
    std::vector<SimplexId> star_begin, star;
    std::vector<SimplexId> upper;
    std::vector<uint64_t> pairs;
  };
  // Blocks go in windows: each window is computed in parallel, then appended in block order to
  // the final arrays, whose upper bounds (6 edges and 4 triangles per tetrahedron) are reserved
  // but untouched, so memory grows by what is written and no second copy of the faces exists.
  constexpr int32_t kWindow = 256;
  std::vector<BlockFaces> faces(std::min(num_blocks, kWindow));
  std::vector<std::vector<int32_t>> neighbors(num_blocks);
  std::vector<Scratch> scratch(std::max(threads, 1));
  t.edge_vertices_.reserve(2 * 6 * size_t(nt));
  t.triangle_vertices_.reserve(3 * 4 * size_t(nt));
  t.triangle_boundary_.reserve(4 * size_t(nt));
  t.vertex_edge_begin_.assign(nv + 1, 0);
  t.vertex_triangle_begin_.assign(nv + 1, 0);
  for (int32_t window = 0; window < num_blocks; window += kWindow) {
    const int32_t window_size = std::min(kWindow, num_blocks - window);
    ParallelFor(window_size, threads, [&](int64_t index, int thread) {
      const int32_t b = window + static_cast<int32_t>(index);
      const SimplexId vbegin = t.block_vertex_begin_[b], vend = t.block_vertex_begin_[b + 1];
      Scratch& sc = scratch[thread];
      BlockFaces& out = faces[index];
      out.edges.clear();
      out.triangles.clear();
      out.triangle_boundary.clear();
      std::vector<int32_t>& adjacent = neighbors[b];
      const auto external = t.external_tetrahedra(b);
      const SimplexId tet_begin = t.block_tet_begin_[b], tet_end = t.block_tet_begin_[b + 1];
      const auto for_each_tet = [&](auto&& fn) {
        for (SimplexId tet : external) fn(tet, &t.tet_vertices_[4 * size_t(tet)]);
        for (SimplexId tet = tet_begin; tet < tet_end; ++tet) {
          fn(tet, &t.tet_vertices_[4 * size_t(tet)]);
        }
      };
      // Stars of the internal vertices (CSR, counting sort).
      sc.star_begin.assign(size_t(vend - vbegin) + 1, 0);
      for_each_tet([&](SimplexId, const SimplexId* s) {
        for (int k = 0; k < 4; ++k) {
          if (s[k] >= vbegin && s[k] < vend) {
            ++sc.star_begin[s[k] - vbegin + 1];
          } else {
            adjacent.push_back(t.vertex_block_[s[k]]);
          }
        }
      });
      for (size_t i = 1; i < sc.star_begin.size(); ++i) sc.star_begin[i] += sc.star_begin[i - 1];
      sc.star.resize(sc.star_begin.back());
      for_each_tet([&](SimplexId tet, const SimplexId* s) {
        for (int k = 0; k < 4; ++k) {
          if (s[k] >= vbegin && s[k] < vend) sc.star[sc.star_begin[s[k] - vbegin]++] = tet;
        }
      });
      // star_begin[i] now ends vertex i's star.
      SimplexId star_from = 0;
      for (SimplexId v = vbegin; v < vend; ++v) {
        const SimplexId star_to = sc.star_begin[v - vbegin];
        sc.upper.clear();
        sc.pairs.clear();
        for (SimplexId i = star_from; i < star_to; ++i) {
          const SimplexId* s = &t.tet_vertices_[4 * size_t(sc.star[i])];
          int p = 0;
          while (s[p] != v) ++p;
          for (int j = p + 1; j < 4; ++j) {
            sc.upper.push_back(s[j]);
            for (int k = j + 1; k < 4; ++k) {
              sc.pairs.push_back(uint64_t(uint32_t(s[j])) << 32 | uint32_t(s[k]));
            }
          }
        }
        star_from = star_to;
        std::sort(sc.upper.begin(), sc.upper.end());
        sc.upper.erase(std::unique(sc.upper.begin(), sc.upper.end()), sc.upper.end());
        for (SimplexId w : sc.upper) out.edges.push_back(uint64_t(uint32_t(v)) << 32 | uint32_t(w));
        std::sort(sc.pairs.begin(), sc.pairs.end());
        for (size_t read = 0; read < sc.pairs.size();) {
          size_t run = read + 1;
          while (run < sc.pairs.size() && sc.pairs[run] == sc.pairs[read]) ++run;
          out.triangles.push_back(
              {v, SimplexId(sc.pairs[read] >> 32), SimplexId(sc.pairs[read] & 0xffffffffu)});
          out.triangle_boundary.push_back(run - read == 1);
          read = run;
        }
      }
      std::sort(adjacent.begin(), adjacent.end());
      adjacent.erase(std::unique(adjacent.begin(), adjacent.end()), adjacent.end());
      adjacent.shrink_to_fit();
    });
    for (int32_t index = 0; index < window_size; ++index) {
      const BlockFaces& bf = faces[index];
      for (uint64_t key : bf.edges) {
        const SimplexId a = SimplexId(key >> 32);
        t.edge_vertices_.push_back(a);
        t.edge_vertices_.push_back(SimplexId(key & 0xffffffffu));
        ++t.vertex_edge_begin_[a + 1];
      }
      for (size_t i = 0; i < bf.triangles.size(); ++i) {
        t.triangle_vertices_.insert(t.triangle_vertices_.end(), bf.triangles[i].begin(),
                                    bf.triangles[i].end());
        t.triangle_boundary_.push_back(bf.triangle_boundary[i]);
        ++t.vertex_triangle_begin_[bf.triangles[i][0] + 1];
      }
    }
  }
  faces.clear();

  if (t.edge_vertices_.size() / 2 > INT32_MAX || t.triangle_vertices_.size() / 3 > INT32_MAX) {
    return absl::ResourceExhaustedError(absl::StrCat("mesh: ", t.triangle_vertices_.size() / 3,
                                                     " triangles exceed the 32-bit id range"));
  }
  for (SimplexId v = 0; v < nv; ++v) {
    t.vertex_edge_begin_[v + 1] += t.vertex_edge_begin_[v];
    t.vertex_triangle_begin_[v + 1] += t.vertex_triangle_begin_[v];
  }

  t.block_neighbor_offsets_.assign(num_blocks + 1, 0);
  for (int32_t b = 0; b < num_blocks; ++b) {
    t.block_neighbor_offsets_[b + 1] =
        t.block_neighbor_offsets_[b] + static_cast<int32_t>(neighbors[b].size());
  }
  t.block_neighbors_.reserve(t.block_neighbor_offsets_.back());
  for (const auto& n : neighbors) {
    t.block_neighbors_.insert(t.block_neighbors_.end(), n.begin(), n.end());
  }
  return topo;
}

}  // namespace actopo
