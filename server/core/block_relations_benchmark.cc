// Block relation throughput: every block of a lattice mesh, one relation per benchmark.
//
//   build/server/core/block_relations_benchmark --benchmark_min_time=0.5
//
// items_per_second counts simplices whose relation was computed; bytes_per_second the size of
// the produced relation arrays.
#include "benchmark/benchmark.h"
#include "server/core/block_relations.h"
#include "server/core/partition.h"
#include "server/core/testing/test_meshes.h"

namespace actopo {
namespace {

const std::shared_ptr<const Topology>& BenchTopology() {
  static const std::shared_ptr<const Topology> topology = [] {
    const Mesh mesh = testing::Lattice(41, 41, 41, 1);  // 68,921 vertices, 384,000 tetrahedra
    return *Topology::Build(mesh, OctreeBlocks(mesh.points, {.bucket_capacity = 1000}));
  }();
  return topology;
}

void BM_BlockRelation(benchmark::State& state) {
  const Relation r = static_cast<Relation>(state.range(0));
  const Topology& topo = *BenchTopology();
  BlockScratch scratch;
  int64_t items = 0, bytes = 0;
  for (auto _ : state) {
    for (int32_t b = 0; b < topo.num_blocks(); ++b) {
      RelationBlock rb = ComputeBlockRelation(topo, r, b, scratch);
      items += rb.count;
      bytes += rb.bytes();
      benchmark::DoNotOptimize(rb.values.data());
    }
  }
  state.SetItemsProcessed(items);
  state.SetBytesProcessed(bytes);
  state.SetLabel(std::string(RelationName(r)));
}

void AllComputedRelations(benchmark::internal::Benchmark* b) {
  for (Relation r : AllRelations()) {
    if (!IsStatic(r)) b->Arg(Index(r));
  }
}

BENCHMARK(BM_BlockRelation)->Apply(AllComputedRelations)->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace actopo

BENCHMARK_MAIN();
