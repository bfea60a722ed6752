#include "server/core/topology.h"

#include <algorithm>
#include <map>
#include <numeric>
#include <random>
#include <set>
#include <thread>

#include "gmock/gmock.h"
#include "gtest/gtest.h"
#include "server/core/partition.h"
#include "server/core/testing/oracle.h"
#include "server/core/testing/status.h"
#include "server/core/testing/test_meshes.h"

namespace actopo {
namespace {

std::shared_ptr<const Topology> BuildOrDie(const Mesh& m, int capacity, int threads = 2) {
  auto t = Topology::Build(m, OctreeBlocks(m.points, {.bucket_capacity = capacity}),
                           {.threads = threads});
  EXPECT_TRUE(t.ok()) << t.status();
  return *t;
}

TEST(Topology, PermutationsAndBlockOrder) {
  const Mesh m = testing::Lattice(6, 5, 4, 99);
  for (int capacity : {1, 7, 100}) {
    auto topo = BuildOrDie(m, capacity);
    const SimplexId nv = topo->num_vertices();
    ASSERT_EQ(nv, m.num_vertices());
    for (SimplexId v = 0; v < nv; ++v) {
      EXPECT_EQ(topo->vertex_internal_id(topo->vertex_input_id(v)), v);
      const int32_t b = topo->vertex_block(v);
      EXPECT_GE(v, topo->block_vertex_begin(b));
      EXPECT_LT(v, topo->block_vertex_begin(b + 1));
    }
    for (SimplexId t = 0; t < topo->num_tetrahedra(); ++t) {
      const SimplexId input = topo->tetrahedron_input_id(t);
      EXPECT_EQ(topo->tetrahedron_internal_id(input), t);
      std::vector<SimplexId> expected;
      for (int k = 0; k < 4; ++k) {
        expected.push_back(topo->vertex_internal_id(m.tetrahedra[4 * size_t(input) + k]));
      }
      std::sort(expected.begin(), expected.end());
      const auto got = topo->tetrahedron(t);
      EXPECT_TRUE(std::equal(got.begin(), got.end(), expected.begin())) << "tet " << t;
      // Grouped by the block of the lowest vertex, in block order.
      const int32_t b = topo->block_of(3, t);
      EXPECT_GE(t, topo->block_tetrahedron_begin(b));
      EXPECT_LT(t, topo->block_tetrahedron_begin(b + 1));
      if (t > 0) {
        EXPECT_LE(topo->block_of(3, t - 1), b);
      }
    }
  }
}

TEST(Topology, SameForAnyThreadCount) {
  const Mesh m = testing::Lattice(9, 8, 7, 5);
  auto one = BuildOrDie(m, 20, /*threads=*/1);
  for (int threads : {2, 3}) {
    auto many = BuildOrDie(m, 20, threads);
    ASSERT_EQ(many->num_blocks(), one->num_blocks());
    for (SimplexId t = 0; t < one->num_tetrahedra(); ++t) {
      ASSERT_EQ(many->tetrahedron_input_id(t), one->tetrahedron_input_id(t)) << threads;
    }
    for (int32_t b = 0; b < one->num_blocks(); ++b) {
      const auto a = one->external_tetrahedra(b), c = many->external_tetrahedra(b);
      EXPECT_TRUE(std::equal(a.begin(), a.end(), c.begin(), c.end())) << "block " << b;
      // Tetrahedra of a block by lowest vertex, then in input order (stable sorts).
      for (SimplexId t = one->block_tetrahedron_begin(b) + 1;
           t < one->block_tetrahedron_begin(b + 1); ++t) {
        const auto key = [&](SimplexId tet) {
          return std::make_pair(one->tetrahedron(tet)[0], one->tetrahedron_input_id(tet));
        };
        EXPECT_LT(key(t - 1), key(t));
      }
    }
    ASSERT_EQ(many->num_triangles(), one->num_triangles());
    for (SimplexId f = 0; f < one->num_triangles(); ++f) {
      ASSERT_EQ(many->triangle(f), one->triangle(f));
      ASSERT_EQ(many->triangle_on_boundary(f), one->triangle_on_boundary(f));
    }
  }
}

// A caller may free the tetrahedra once Build says it has read them: the encoding is the same.
TEST(Topology, TetrahedraFreedWhenReadGiveTheSameEncoding) {
  const Mesh m = testing::Lattice(9, 8, 7, 5);
  const std::vector<int32_t> blocks = OctreeBlocks(m.points, {.bucket_capacity = 20});
  auto kept = OkValue(Topology::Build(m, blocks, {.threads = 2}));
  Mesh freed = m;
  int calls = 0;
  auto built = Topology::Build(
      freed, blocks,
      {.threads = 2, .tetrahedra_read = [&](const Topology& partial) {
         ++calls;
         // Its tetrahedra are final by then.
         for (SimplexId x = 0; x < partial.num_tetrahedra(); ++x) {
           ASSERT_TRUE(std::ranges::equal(partial.tetrahedron(x), kept->tetrahedron(x)));
           ASSERT_EQ(partial.tetrahedron_input_id(x), kept->tetrahedron_input_id(x));
         }
         std::vector<SimplexId>().swap(freed.tetrahedra);
       }});
  ASSERT_TRUE(built.ok()) << built.status();
  EXPECT_EQ(calls, 1);
  EXPECT_TRUE(freed.tetrahedra.empty());
  const Topology& t = **built;
  ASSERT_EQ(t.num_tetrahedra(), kept->num_tetrahedra());
  ASSERT_EQ(t.num_edges(), kept->num_edges());
  ASSERT_EQ(t.num_triangles(), kept->num_triangles());
  for (SimplexId x = 0; x < t.num_tetrahedra(); ++x) {
    ASSERT_TRUE(std::ranges::equal(t.tetrahedron(x), kept->tetrahedron(x)));
    ASSERT_EQ(t.tetrahedron_input_id(x), kept->tetrahedron_input_id(x));
  }
  for (SimplexId f = 0; f < t.num_triangles(); ++f) {
    ASSERT_EQ(t.triangle(f), kept->triangle(f));
    ASSERT_EQ(t.triangle_on_boundary(f), kept->triangle_on_boundary(f));
  }
  for (SimplexId e = 0; e < t.num_edges(); ++e) ASSERT_EQ(t.edge(e), kept->edge(e));
}

// The corners' order is taken while encoding, and releasing the input tetrahedra's pages as they
// are read changes nothing in the encoding; the released pages read as zeros.
TEST(Topology, CornersTakenWhileTetrahedraAreReleased) {
  Mesh m = testing::Lattice(40, 40, 40, 3);  // 365k tetrahedra: several release strides
  std::mt19937 rng(11);
  for (size_t t = 0; t < m.tetrahedra.size(); t += 4) {
    std::shuffle(m.tetrahedra.begin() + t, m.tetrahedra.begin() + t + 4, rng);
  }
  const std::vector<int32_t> blocks = OctreeBlocks(m.points, {.bucket_capacity = 500});
  auto kept = OkValue(Topology::Build(m, blocks, {.threads = 2}));
  Mesh released = m;
  std::vector<uint8_t> corners;
  auto built = Topology::Build(
      released, blocks, {.threads = 2, .input_corners = &corners, .release_tetrahedra = true});
  ASSERT_TRUE(built.ok()) << built.status();
  const Topology& t = **built;
  const auto zeros = std::count(released.tetrahedra.begin(), released.tetrahedra.end(), 0);
  EXPECT_GT(zeros, int64_t(released.tetrahedra.size()) / 2);
  ASSERT_EQ(corners.size(), size_t(t.num_tetrahedra()));
  for (SimplexId x = 0; x < t.num_tetrahedra(); ++x) {
    ASSERT_TRUE(std::ranges::equal(t.tetrahedron(x), kept->tetrahedron(x)));
    ASSERT_EQ(t.tetrahedron_input_id(x), kept->tetrahedron_input_id(x));
    const SimplexId* given = &m.tetrahedra[4 * size_t(t.tetrahedron_input_id(x))];
    int positions = 0;
    for (int k = 0; k < 4; ++k) {
      const int p = (corners[x] >> (2 * k)) & 3;
      positions |= 1 << p;
      ASSERT_EQ(t.vertex_internal_id(given[p]), t.tetrahedron(x)[k]) << "tet " << x;
    }
    ASSERT_EQ(positions, 0xF) << "tet " << x;
  }
  for (SimplexId f = 0; f < t.num_triangles(); ++f) ASSERT_EQ(t.triangle(f), kept->triangle(f));
}

// Without faces (and with the points freed first) everything but edges and triangles is the same.
TEST(Topology, WithoutFacesTheRestIsTheSame) {
  const Mesh m = testing::Lattice(9, 8, 7, 5);
  const std::vector<int32_t> blocks = OctreeBlocks(m.points, {.bucket_capacity = 20});
  auto full = OkValue(Topology::Build(m, blocks, {.threads = 2}));
  Mesh no_points = m;
  no_points.points.clear();
  auto built = Topology::Build(no_points, blocks, {.threads = 2, .faces = false});
  ASSERT_TRUE(built.ok()) << built.status();
  const Topology& t = **built;
  EXPECT_TRUE(full->has_faces());
  EXPECT_FALSE(t.has_faces());
  EXPECT_EQ(t.num_edges(), 0);
  EXPECT_EQ(t.num_triangles(), 0);
  ASSERT_EQ(t.num_vertices(), full->num_vertices());
  ASSERT_EQ(t.num_tetrahedra(), full->num_tetrahedra());
  ASSERT_EQ(t.num_blocks(), full->num_blocks());
  for (SimplexId v = 0; v < t.num_vertices(); ++v) {
    ASSERT_EQ(t.vertex_input_id(v), full->vertex_input_id(v));
  }
  for (SimplexId x = 0; x < t.num_tetrahedra(); ++x) {
    ASSERT_TRUE(std::ranges::equal(t.tetrahedron(x), full->tetrahedron(x)));
    ASSERT_EQ(t.tetrahedron_input_id(x), full->tetrahedron_input_id(x));
  }
  for (int32_t b = 0; b < t.num_blocks(); ++b) {
    EXPECT_TRUE(std::ranges::equal(t.block_neighbors(b), full->block_neighbors(b)));
    EXPECT_TRUE(std::ranges::equal(t.external_tetrahedra(b), full->external_tetrahedra(b)));
  }
  const TopologyBytes bytes = t.bytes();
  EXPECT_EQ(bytes.edges + bytes.triangles, 0);
  EXPECT_EQ(bytes.tetrahedra, full->bytes().tetrahedra);
  // The vertex count comes from the blocks; points, when kept, must agree with them.
  const std::vector<int32_t> short_blocks(blocks.begin(), blocks.end() - 1);
  EXPECT_THAT(Topology::Build(m, short_blocks, {.faces = false}).status().message(),
              ::testing::HasSubstr("block ids for"));
}

// Every edge and triangle accessor of `t` agrees with `full`'s, which was built with its faces.
void ExpectSameFaces(const Topology& t, const Topology& full) {
  ASSERT_TRUE(t.has_faces());
  ASSERT_EQ(t.num_edges(), full.num_edges());
  ASSERT_EQ(t.num_triangles(), full.num_triangles());
  for (SimplexId e = 0; e < t.num_edges(); ++e) {
    ASSERT_EQ(t.edge(e), full.edge(e)) << "edge " << e;
    ASSERT_EQ(t.edge_first_triangle(e), full.edge_first_triangle(e));
  }
  for (SimplexId f = 0; f < t.num_triangles(); ++f) {
    ASSERT_EQ(t.triangle(f), full.triangle(f)) << "triangle " << f;
    ASSERT_EQ(t.triangle_on_boundary(f), full.triangle_on_boundary(f)) << "triangle " << f;
  }
  for (SimplexId v = 0; v <= t.num_vertices(); ++v) {
    ASSERT_EQ(t.vertex_first_edge(v), full.vertex_first_edge(v));
  }
  for (int32_t b = 0; b <= t.num_blocks(); ++b) {
    ASSERT_EQ(t.block_begin(1, b), full.block_begin(1, b));
    ASSERT_EQ(t.block_begin(2, b), full.block_begin(2, b));
  }
  EXPECT_EQ(t.bytes().total(), full.bytes().total());
}

// Faces built later, by several callers at once, are the faces Build makes.
TEST(Topology, FacesEnsuredLaterAreTheSame) {
  const Mesh m = testing::Lattice(9, 8, 7, 5);
  const std::vector<int32_t> blocks = OctreeBlocks(m.points, {.bucket_capacity = 20});
  auto full = OkValue(Topology::Build(m, blocks, {.threads = 2}));
  auto t = OkValue(Topology::Build(m, blocks, {.threads = 2, .faces = false}));
  ASSERT_FALSE(t->has_faces());
  // Readers of the rest of the topology go on meanwhile (ThreadSanitizer checks they may).
  std::vector<std::thread> threads;
  std::vector<absl::Status> ensured(4);
  std::atomic<int64_t> read{0};
  for (int i = 0; i < 4; ++i) {
    threads.emplace_back([&, i] {
      int64_t sum = 0;
      for (SimplexId x = 0; x < t->num_tetrahedra(); ++x) sum += t->tetrahedron(x)[3];
      read += sum;
      // Before the faces are there no edge is counted, after them every one.
      const SimplexId edges = t->num_edges();
      EXPECT_TRUE(edges == 0 || edges == full->num_edges()) << edges;
      ensured[i] = t->EnsureFaces({}, {.threads = 2});
    });
  }
  for (std::thread& thread : threads) thread.join();
  for (const absl::Status& s : ensured) EXPECT_TRUE(s.ok()) << s;
  EXPECT_GT(read.load(), 0);
  ExpectSameFaces(*t, *full);
  EXPECT_TRUE(t->EnsureFaces().ok());  // once built, a no-op
  EXPECT_EQ(t->FindTriangle(full->triangle(3)[0], full->triangle(3)[1], full->triangle(3)[2]), 3);
}

TEST(Topology, EnsuringFacesTwiceOnAFullTopologyChangesNothing) {
  const Mesh m = testing::Lattice(5, 5, 5, 2);
  auto full = BuildOrDie(m, 9);
  const int64_t bytes = full->bytes().total();
  EXPECT_TRUE(full->EnsureFaces().ok());
  EXPECT_EQ(full->bytes().total(), bytes);
}

TEST(Topology, EdgesTrianglesAndBoundaryMatchOracle) {
  for (const Mesh& m : {testing::Lattice(5, 4, 4, 1), testing::NonManifold(),
                        testing::TwoComponents(), testing::SingleTetrahedron()}) {
    for (int capacity : {1, 7, 1000}) {
      auto topo = BuildOrDie(m, capacity);
      testing::RelationOracle oracle(*topo);
      bool crowded = false;  // a triangle with three tetrahedra or more
      for (const auto& star : oracle.rows(Relation::kFT)) crowded |= star.size() > 2;
      EXPECT_EQ(topo->has_crowded_triangles(), crowded);
      int64_t answered = 0;  // triangles TriangleTetrahedraInRun answers
      ASSERT_EQ(topo->num_edges(), SimplexId(oracle.edges().size()));
      ASSERT_EQ(topo->num_triangles(), SimplexId(oracle.triangles().size()));
      for (SimplexId e = 0; e < topo->num_edges(); ++e) {
        EXPECT_EQ(topo->edge(e)[0], oracle.edges()[e][0]);
        EXPECT_EQ(topo->edge(e)[1], oracle.edges()[e][1]);
        EXPECT_EQ(topo->FindEdge(oracle.edges()[e][0], oracle.edges()[e][1]), e);
        EXPECT_EQ(topo->block_of(1, e), topo->vertex_block(oracle.edges()[e][0]));
      }
      for (SimplexId f = 0; f < topo->num_triangles(); ++f) {
        const auto& tri = oracle.triangles()[f];
        EXPECT_EQ(topo->FindTriangle(tri[0], tri[1], tri[2]), f);
        const auto decoded = topo->triangle(f);
        EXPECT_TRUE(std::equal(decoded.begin(), decoded.end(), tri.begin())) << "triangle " << f;
        const SimplexId e = topo->triangle_edge(f);
        EXPECT_EQ(e, topo->FindEdge(tri[0], tri[1]));
        EXPECT_GE(f, topo->edge_first_triangle(e));
        EXPECT_LT(f, topo->edge_first_triangle(e + 1));
        EXPECT_EQ(topo->block_of(2, f), topo->vertex_block(tri[0]));
        EXPECT_EQ(topo->triangle_on_boundary(f), oracle.rows(Relation::kFB)[f][0] == 1)
            << "triangle " << f;
        // When the lowest vertex's run answers, it gives the whole star.
        std::array<SimplexId, 2> in_run;
        const int n = topo->TriangleTetrahedraInRun(f, in_run);
        if (n >= 0) {
          ++answered;
          EXPECT_EQ(std::vector<SimplexId>(in_run.begin(), in_run.begin() + n),
                    oracle.rows(Relation::kFT)[f])
              << "triangle " << f;
        }
      }
      if (crowded) {
        EXPECT_EQ(answered, 0);
      } else {
        EXPECT_GT(answered, 0);  // the run's path is taken, not only the star's
      }
      for (int32_t b = 0; b < topo->num_blocks(); ++b) {
        for (int dim = 0; dim < 4; ++dim) {
          for (SimplexId s = topo->block_begin(dim, b); s < topo->block_begin(dim, b + 1); ++s) {
            EXPECT_EQ(topo->block_of(dim, s), b);
          }
        }
      }
    }
  }
}

// Two blocks of alternate x-slices, 70k vertices each: every edge along x joins vertices more than
// 65,535 ids apart, whose upper (and third) vertices the runs keep whole (NarrowIds), as are the
// tetrahedra across the blocks (NarrowTetrahedra). Every tetrahedron, edge and triangle is decoded
// and found again, and tuples that are not there are not found.
TEST(Topology, FacesAndTetrahedraFarInIdAreKeptWhole) {
  const Mesh m = testing::Lattice(52, 52, 52);  // 140,608 vertices, 796k tetrahedra
  auto built = Topology::Build(m, OkValue(LabelBlocks(testing::SliceLabels(m, 2))));
  ASSERT_TRUE(built.ok()) << built.status();
  const Topology& topo = **built;
  ASSERT_EQ(topo.num_blocks(), 2);
  // Every tetrahedron against the mesh's, and every edge and triangle, as sorted internal tuples:
  // their ids are their ranks.
  std::vector<std::array<SimplexId, 2>> edges;
  std::vector<std::array<SimplexId, 3>> triangles;
  int64_t far_tetrahedra = 0;
  for (SimplexId t = 0; t < topo.num_tetrahedra(); ++t) {
    const auto s = topo.tetrahedron(t);
    std::array<SimplexId, 4> given;
    for (int k = 0; k < 4; ++k) {
      given[k] =
          topo.vertex_internal_id(m.tetrahedra[4 * size_t(topo.tetrahedron_input_id(t)) + k]);
    }
    std::sort(given.begin(), given.end());
    ASSERT_EQ(s, given) << "tetrahedron " << t;
    ASSERT_EQ(topo.FindTetrahedron(s[0], s[1], s[2], s[3]), t);
    ASSERT_EQ(topo.block_of(3, t), topo.vertex_block(s[0]));
    far_tetrahedra += s[3] - s[0] >= 65535;
    for (int i = 0; i < 4; ++i) {
      for (int j = i + 1; j < 4; ++j) {
        edges.push_back({s[i], s[j]});
        for (int k = j + 1; k < 4; ++k) triangles.push_back({s[i], s[j], s[k]});
      }
    }
  }
  std::sort(edges.begin(), edges.end());
  edges.erase(std::unique(edges.begin(), edges.end()), edges.end());
  std::sort(triangles.begin(), triangles.end());
  triangles.erase(std::unique(triangles.begin(), triangles.end()), triangles.end());
  ASSERT_EQ(topo.num_edges(), SimplexId(edges.size()));
  ASSERT_EQ(topo.num_triangles(), SimplexId(triangles.size()));
  const auto far = [](SimplexId a, SimplexId b) { return b - a >= 65535; };
  int64_t far_edges = 0, far_triangles = 0;
  for (SimplexId e = 0; e < topo.num_edges(); ++e) {
    const auto [a, b] = edges[e];
    ASSERT_EQ(topo.edge(e), edges[e]) << "edge " << e;
    ASSERT_EQ(topo.FindEdge(a, b), e);
    // The next vertex up is an edge's upper vertex only when the list says so.
    const bool next_is_edge =
        std::binary_search(edges.begin(), edges.end(), std::array<SimplexId, 2>{a, b + 1});
    if (b + 1 < topo.num_vertices()) {
      ASSERT_EQ(topo.FindEdge(a, b + 1) >= 0, next_is_edge) << a << " " << b + 1;
    }
    far_edges += far(a, b);
  }
  for (SimplexId f = 0; f < topo.num_triangles(); ++f) {
    const auto [a, b, c] = triangles[f];
    ASSERT_EQ(topo.triangle(f), triangles[f]) << "triangle " << f;
    ASSERT_EQ(topo.FindTriangle(a, b, c), f);
    const bool next_is_triangle = std::binary_search(triangles.begin(), triangles.end(),
                                                     std::array<SimplexId, 3>{a, b, c + 1});
    if (c + 1 < topo.num_vertices()) {
      ASSERT_EQ(topo.FindTriangle(a, b, c + 1) >= 0, next_is_triangle) << a << " " << b;
    }
    far_triangles += far(a, c);
  }
  // The whole-id path is taken, and often: 51 x 52 x 52 edges along x. (Bucketing takes it too:
  // a block of 70k vertices puts lowest vertices past 16 bits from their block's first.)
  EXPECT_GT(far_tetrahedra, 100000);
  EXPECT_GT(far_edges, 100000);
  EXPECT_GT(far_triangles, 100000);
}

// Runs of items with long stretches of empty runs (unused vertices): offsets past 8 bits take
// the binary-search path. Built on 1 and 3 threads: the items span several of Build's parallel
// stretches (262,144 items each), with empty runs at their edges.
TEST(RunLookup, MatchesLinearScanAcrossEmptyStretches) {
  std::vector<SimplexId> begin = {0};
  const auto add_runs = [&](int runs, SimplexId items_each) {
    for (int i = 0; i < runs; ++i) begin.push_back(begin.back() + items_each);
  };
  add_runs(100, 3);
  add_runs(300, 0);  // just past 8 bits
  add_runs(2, 1);
  add_runs(70000, 0);  // one 64-item stretch will span these
  add_runs(5, 1);
  add_runs(200000, 0);
  add_runs(3, 70);
  add_runs(10, 0);
  add_runs(87381, 3);  // up to item 262,658: past the first stretch
  add_runs(90000, 0);
  add_runs(100000, 5);
  add_runs(3, 0);
  const SimplexId items = begin.back();
  for (int threads : {1, 3}) {
    RunLookup lookup;
    lookup.Build(begin, items, threads);
    SimplexId run = 0;
    for (SimplexId x = 0; x < items; ++x) {
      while (begin[run + 1] <= x) ++run;
      ASSERT_EQ(lookup.Owner(begin, x), run) << "item " << x << ", " << threads << " threads";
    }
  }
}

// Run starts with runs of 0 to 70,000 items: the groups whose items do not fit their distances
// keep their starts whole, the others are narrow, and a run's pair of starts may cross from one
// kind of group to the other. Both widths the topology uses, built on 1 and 3 threads.
template <class Starts>
void ExpectStartsMatch(std::span<const SimplexId> starts, size_t distance_bytes) {
  for (int threads : {1, 3}) {
    Starts narrow;
    narrow.Assign(starts, threads);
    ASSERT_EQ(narrow.size(), starts.size());
    for (size_t i = 0; i < starts.size(); ++i) {
      ASSERT_EQ(narrow[i], starts[i]) << "entry " << i << ", " << threads << " threads";
      if (i + 1 < starts.size()) {
        ASSERT_EQ(narrow.Run(i), std::make_pair(starts[i], starts[i + 1])) << "run " << i;
      }
    }
    // Both kinds of group are there: whole starts take 4 bytes each, narrow ones fewer.
    EXPECT_GT(narrow.bytes(), int64_t(distance_bytes * starts.size() + 64 * 4));
    EXPECT_LT(narrow.bytes(), int64_t(4 * starts.size()));
  }
}

TEST(RunStarts, MatchesTheStartsGivenAcrossWideGroups) {
  uint64_t state = 12345;
  const auto make_starts = [&](SimplexId wide_run, int mostly_below) {
    std::vector<SimplexId> starts = {0};
    for (int i = 0; i < 20000; ++i) {
      state = state * 6364136223846793005u + 1442695040888963407u;
      const int kind = int(state >> 56);  // 0..255
      // Mostly short runs, a quarter empty, one in 256 too long for its group.
      const SimplexId items = kind == 0   ? wide_run
                              : kind < 64 ? 0
                                          : SimplexId((state >> 32) % mostly_below);
      starts.push_back(starts.back() + items);
    }
    return starts;
  };
  ExpectStartsMatch<RunStarts<uint16_t, 6>>(make_starts(70000, 40), 2);
  ExpectStartsMatch<RunStarts<uint8_t, 4>>(make_starts(300, 4), 1);
}

// Lists of ascending ids with gaps below and above 16 bits, first ids far from 0, and empty
// lists: read back in order, with their sizes. Built on 1 and 3 threads.
TEST(AscendingIdLists, ReadsBackListsWithFarGaps) {
  std::vector<SimplexId> offsets = {0}, ids;
  uint64_t state = 777;
  for (int list = 0; list < 500; ++list) {
    state = state * 6364136223846793005u + 1442695040888963407u;
    const int length = list % 7 == 0 ? 0 : int(state >> 58);  // 0..63
    SimplexId id = SimplexId((state >> 20) % 200000);
    for (int i = 0; i < length; ++i) {
      state = state * 6364136223846793005u + 1442695040888963407u;
      // One gap in 8 past 16 bits (65,535 itself included), the others short.
      const int kind = int(state >> 61);
      id += kind == 0 ? 65535 + SimplexId((state >> 30) % 100000) : SimplexId((state >> 30) % 300);
      ids.push_back(id);
    }
    offsets.push_back(SimplexId(ids.size()));
  }
  for (int threads : {1, 3}) {
    AscendingIdLists lists;
    lists.Assign(offsets, ids, threads);
    for (int32_t k = 0; k + 1 < int32_t(offsets.size()); ++k) {
      const auto list = lists.list(k);
      ASSERT_EQ(list.size(), size_t(offsets[k + 1] - offsets[k])) << "list " << k;
      EXPECT_EQ(std::vector<SimplexId>(list.begin(), list.end()),
                std::vector<SimplexId>(ids.begin() + offsets[k], ids.begin() + offsets[k + 1]))
          << "list " << k << ", " << threads << " threads";
    }
    // Some ids are kept whole, most are 2 bytes.
    EXPECT_GT(lists.bytes(), int64_t(2 * ids.size() + 4 * offsets.size() * 2 + 4 * 100));
    EXPECT_LT(lists.bytes(), int64_t(4 * ids.size()));
  }
}

TEST(Topology, FindRejectsAbsentSimplices) {
  auto topo = BuildOrDie(testing::NonManifold(), 3);
  // Vertices 0 and 9 are in different components.
  const SimplexId a = topo->vertex_internal_id(0), b = topo->vertex_internal_id(9);
  EXPECT_EQ(topo->FindEdge(std::min(a, b), std::max(a, b)), -1);
  const SimplexId c = topo->vertex_internal_id(13);
  std::array<SimplexId, 3> t = {a, b, c};
  std::sort(t.begin(), t.end());
  EXPECT_EQ(topo->FindTriangle(t[0], t[1], t[2]), -1);
}

// Against a brute-force oracle: every tetrahedron's tuple finds it, and random tuples (mostly
// absent, some sharing a face or a lowest vertex with a tetrahedron) find one exactly when the
// mesh's set of sorted tuples holds them.
TEST(Topology, FindTetrahedronMatchesBruteForce) {
  for (const Mesh& m : {testing::Lattice(5, 4, 4, 1), testing::NonManifold(),
                        testing::TwoComponents(), testing::SingleTetrahedron()}) {
    for (int capacity : {1, 7, 1000}) {
      auto topo = BuildOrDie(m, capacity);
      std::map<std::array<SimplexId, 4>, SimplexId> tuples;
      for (SimplexId t = 0; t < topo->num_tetrahedra(); ++t) {
        std::array<SimplexId, 4> v;
        const SimplexId input = topo->tetrahedron_input_id(t);
        for (int k = 0; k < 4; ++k) {
          v[k] = topo->vertex_internal_id(m.tetrahedra[4 * size_t(input) + k]);
        }
        std::sort(v.begin(), v.end());
        tuples[v] = t;
      }
      for (const auto& [v, t] : tuples) {
        EXPECT_EQ(topo->FindTetrahedron(v[0], v[1], v[2], v[3]), t);
      }
      // Each vertex's run of tetrahedra it is the lowest vertex of: exactly those.
      std::vector<std::vector<SimplexId>> lowest_of(size_t(topo->num_vertices()));
      for (const auto& [v, t] : tuples) lowest_of[v[0]].push_back(t);
      for (SimplexId v = 0; v < topo->num_vertices(); ++v) {
        std::sort(lowest_of[v].begin(), lowest_of[v].end());
        const auto [first, end] = topo->lowest_vertex_tetrahedra(v);
        std::vector<SimplexId> run(size_t(end - first));
        std::iota(run.begin(), run.end(), first);
        EXPECT_EQ(run, lowest_of[v]) << "vertex " << v << ", capacity " << capacity;
      }
      std::mt19937 random(capacity);
      const SimplexId nv = topo->num_vertices();
      for (int i = 0; i < 2000; ++i) {
        std::array<SimplexId, 4> v;
        if (i % 2 == 0 && !tuples.empty()) {
          // A tetrahedron with one vertex replaced: often a near miss.
          auto it = tuples.begin();
          std::advance(it, random() % tuples.size());
          v = it->first;
          v[random() % 4] = SimplexId(random() % nv);
        } else {
          for (SimplexId& x : v) x = SimplexId(random() % nv);
        }
        std::sort(v.begin(), v.end());
        if (std::adjacent_find(v.begin(), v.end()) != v.end()) continue;
        const auto it = tuples.find(v);
        EXPECT_EQ(topo->FindTetrahedron(v[0], v[1], v[2], v[3]),
                  it == tuples.end() ? -1 : it->second)
            << v[0] << " " << v[1] << " " << v[2] << " " << v[3];
      }
    }
  }
}

TEST(Topology, ExternalTetrahedraAndBlockAdjacency) {
  const Mesh m = testing::Lattice(7, 6, 5, 4);
  auto topo = BuildOrDie(m, 9);
  std::vector<std::set<int32_t>> adjacency(topo->num_blocks());
  std::vector<std::vector<SimplexId>> external(topo->num_blocks());
  for (SimplexId t = 0; t < topo->num_tetrahedra(); ++t) {
    std::set<int32_t> blocks;
    for (SimplexId v : topo->tetrahedron(t)) blocks.insert(topo->vertex_block(v));
    for (int32_t b : blocks) {
      if (b != topo->block_of(3, t)) external[b].push_back(t);
      for (int32_t c : blocks)
        if (c != b) adjacency[b].insert(c);
    }
  }
  for (int32_t b = 0; b < topo->num_blocks(); ++b) {
    const auto ext = topo->external_tetrahedra(b);
    EXPECT_EQ(std::vector<SimplexId>(ext.begin(), ext.end()), external[b]) << "block " << b;
    for (SimplexId t : ext) EXPECT_LT(t, topo->block_tetrahedron_begin(b));
    const auto adj = topo->block_neighbors(b);
    EXPECT_EQ(std::vector<int32_t>(adj.begin(), adj.end()),
              std::vector<int32_t>(adjacency[b].begin(), adjacency[b].end()));
  }
  const TopologyBytes bytes = topo->bytes();
  EXPECT_GT(bytes.edges, 0);
  EXPECT_EQ(bytes.total(),
            bytes.vertices + bytes.edges + bytes.triangles + bytes.tetrahedra + bytes.blocks);
}

TEST(Topology, RejectsBadBlockArrays) {
  const Mesh m = testing::SingleTetrahedron();
  const std::vector<int32_t> short_blocks = {0, 0};
  EXPECT_THAT(Topology::Build(m, short_blocks).status().message(),
              ::testing::HasSubstr("2 block ids for 4 vertices"));
  const std::vector<int32_t> gap = {0, 2, 2, 0};
  EXPECT_THAT(Topology::Build(m, gap).status().message(),
              ::testing::HasSubstr("block 1 has no vertex"));
}

}  // namespace
}  // namespace actopo

namespace actopo {
namespace {

// Reports of one phase, in order, and a cancel flag set after the `stop_after`-th report.
struct Recorder {
  std::vector<double> fractions;
  std::atomic<bool> cancel{false};
  int stop_after = -1;
  Progress progress() {
    return Progress({.cancel = &cancel, .report = [this](std::string_view, double f) {
                       fractions.push_back(f);
                       if (int(fractions.size()) == stop_after) cancel = true;
                     }});
  }
};

TEST(TopologyProgress, ReportsFromZeroToOneInOrder) {
  const Mesh m = testing::Lattice(12, 11, 10, 5);
  Recorder recorder;
  ASSERT_TRUE(
      Topology::Build(m, OctreeBlocks(m.points, {.bucket_capacity = 3}), {}, recorder.progress())
          .ok());
  ASSERT_GE(recorder.fractions.size(), 4u);
  EXPECT_EQ(recorder.fractions.front(), 0);
  EXPECT_EQ(recorder.fractions.back(), 1);
  EXPECT_TRUE(std::is_sorted(recorder.fractions.begin(), recorder.fractions.end()));
}

TEST(TopologyProgress, StopsAtEveryStepWhenCancelled) {
  const Mesh m = testing::Lattice(12, 11, 10, 5);
  const std::vector<int32_t> blocks = OctreeBlocks(m.points, {.bucket_capacity = 3});
  Recorder all;
  ASSERT_TRUE(Topology::Build(m, blocks, {}, all.progress()).ok());
  // Cancelled after each report in turn: the build stops right there, whatever the step.
  for (int k = 1; k <= int(all.fractions.size()); ++k) {
    Recorder recorder;
    recorder.stop_after = k;
    const auto built = Topology::Build(m, blocks, {}, recorder.progress());
    EXPECT_EQ(built.status().code(), absl::StatusCode::kCancelled) << "after report " << k;
    EXPECT_EQ(int(recorder.fractions.size()), k);
    EXPECT_THAT(built.status().message(), ::testing::HasSubstr("'encode'"));
  }
}

// A stopped EnsureFaces keeps nothing; the next call builds them whole.
TEST(TopologyProgress, AStoppedFaceBuildLeavesNothingAndTheNextOneFinishes) {
  const Mesh m = testing::Lattice(12, 11, 10, 5);
  const std::vector<int32_t> blocks = OctreeBlocks(m.points, {.bucket_capacity = 3});
  auto full = OkValue(Topology::Build(m, blocks, {}));
  auto t = OkValue(Topology::Build(m, blocks, {.faces = false}));
  const int64_t faceless = t->bytes().total();
  Recorder all;
  {
    auto probe = OkValue(Topology::Build(m, blocks, {.faces = false}));
    ASSERT_TRUE(probe->EnsureFaces(all.progress()).ok());
  }
  ASSERT_GE(all.fractions.size(), 4u);  // 0, a report per window of blocks, 0.95, 1
  EXPECT_EQ(all.fractions.front(), 0);
  EXPECT_EQ(all.fractions.back(), 1);
  EXPECT_TRUE(std::is_sorted(all.fractions.begin(), all.fractions.end()));
  // Stopped after each report but the last (which comes once they are built and kept).
  for (int k = 1; k < int(all.fractions.size()); ++k) {
    Recorder recorder;
    recorder.stop_after = k;
    const absl::Status s = t->EnsureFaces(recorder.progress());
    EXPECT_EQ(s.code(), absl::StatusCode::kCancelled) << "after report " << k;
    EXPECT_THAT(s.message(), ::testing::HasSubstr("'faces'"));
    EXPECT_FALSE(t->has_faces());
    EXPECT_EQ(t->num_edges(), 0);
    EXPECT_EQ(t->bytes().total(), faceless);
  }
  ASSERT_TRUE(t->EnsureFaces().ok());
  ExpectSameFaces(*t, *full);
}

TEST(TopologyProgress, APassedDeadlineStopsTheBuild) {
  const Mesh m = testing::Lattice(4, 4, 4, 1);
  const Progress late({.deadline = Progress::Clock::now() - std::chrono::seconds(1)});
  EXPECT_EQ(Topology::Build(m, OctreeBlocks(m.points, {}), {}, late).status().code(),
            absl::StatusCode::kDeadlineExceeded);
}

}  // namespace
}  // namespace actopo
