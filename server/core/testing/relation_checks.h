// Test helpers shared by the core relation tests and the fidelity tests on real meshes.
#ifndef ACTOPO_SERVER_CORE_TESTING_RELATION_CHECKS_H_
#define ACTOPO_SERVER_CORE_TESTING_RELATION_CHECKS_H_

#include <algorithm>
#include <random>
#include <vector>

#include "gtest/gtest.h"
#include "server/core/relation.h"
#include "server/core/testing/oracle.h"
#include "server/core/topology.h"

namespace actopo::testing {

// Every relation of every simplex, in order, equals the oracle's. Returns the number of
// mismatching rows (reports the first few).
template <class Reader>
int CompareWithOracle(Reader& reader, const RelationOracle& oracle, const std::string& label) {
  int mismatches = 0;
  for (Relation r : AllRelations()) {
    const auto& expected = oracle.rows(r);
    const SimplexId n = reader.topology().num_simplices(SourceDimension(r));
    EXPECT_EQ(SimplexId(expected.size()), n) << label << " " << RelationName(r);
    for (SimplexId s = 0; s < n; ++s) {
      const auto got = reader.get(r, s);
      if (!std::equal(got.begin(), got.end(), expected[s].begin(), expected[s].end())) {
        if (++mismatches <= 5) {
          ADD_FAILURE() << label << ": " << RelationName(r) << " of " << s << " differs";
        }
      }
    }
  }
  return mismatches;
}

// A sweep's reads of block b: each of its vertices' star and edges (both held at once), as the
// oracle has them. Returns the number of vertices whose rows differ (reports the first few).
template <class Reader>
int CompareBlockStarsAndEdges(Reader& reader, const RelationOracle& oracle, int32_t b) {
  const Topology& topo = reader.topology();
  int mismatches = 0;
  for (SimplexId v = topo.block_vertex_begin(b); v < topo.block_vertex_begin(b + 1); ++v) {
    const auto star = reader.vertex_star(v);
    const auto edges = reader.vertex_edges(v);
    const auto& vt = oracle.rows(Relation::kVT)[v];
    const auto& ve = oracle.rows(Relation::kVE)[v];
    if (!std::equal(star.begin(), star.end(), vt.begin(), vt.end()) ||
        !std::equal(edges.begin(), edges.end(), ve.begin(), ve.end())) {
      if (++mismatches <= 5) ADD_FAILURE() << "block " << b << ": VT or VE of " << v << " differs";
    }
  }
  return mismatches;
}

// Random access across all relations, holding a span of one relation while reading others, so
// caches evict and the lifetime rule of structure.h is exercised.
template <class Reader>
void CompareRandomAccess(Reader& reader, const RelationOracle& oracle, uint64_t seed, int queries,
                         const std::string& label) {
  std::mt19937_64 rng(seed);
  const auto& vt_expected = oracle.rows(Relation::kVT);
  for (int q = 0; q < queries; ++q) {
    const SimplexId v = SimplexId(rng() % vt_expected.size());
    const auto star = reader.vertex_star(v);
    for (SimplexId t : star) {
      const Relation r = AllRelations()[rng() % kNumRelations];
      if (r == Relation::kVT) continue;
      const SimplexId n = reader.topology().num_simplices(SourceDimension(r));
      const SimplexId s = SourceDimension(r) == 3 ? t : SimplexId(rng() % n);
      const auto got = reader.get(r, s);
      const auto& expected = oracle.rows(r)[s];
      ASSERT_TRUE(std::equal(got.begin(), got.end(), expected.begin(), expected.end()))
          << label << ": " << RelationName(r) << " of " << s;
    }
    ASSERT_TRUE(std::equal(star.begin(), star.end(), vt_expected[v].begin(), vt_expected[v].end()))
        << label << ": vertex_star span of " << v << " changed while reading other relations";
  }
}

}  // namespace actopo::testing

#endif  // ACTOPO_SERVER_CORE_TESTING_RELATION_CHECKS_H_
