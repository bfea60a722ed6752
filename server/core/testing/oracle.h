// Brute-force reference for every relation, built from the tetrahedron list with ordered sets.
// Slow and obviously right; the relation tests compare every structure against it.
#ifndef ACTOPO_SERVER_CORE_TESTING_ORACLE_H_
#define ACTOPO_SERVER_CORE_TESTING_ORACLE_H_

#include <array>
#include <vector>

#include "server/core/mesh.h"
#include "server/core/relation.h"
#include "server/core/topology.h"

namespace actopo::testing {

class RelationOracle {
 public:
  // Uses only the topology's vertex count and tetrahedra (internal ids); edge and triangle ids
  // are re-derived as ranks of the sorted tuples.
  explicit RelationOracle(const Topology& topology);

  const std::vector<std::array<SimplexId, 2>>& edges() const { return edges_; }
  const std::vector<std::array<SimplexId, 3>>& triangles() const { return triangles_; }
  // rows[s] of relation r for every simplex s of its source dimension.
  const std::vector<std::vector<SimplexId>>& rows(Relation r) const { return rows_[Index(r)]; }

 private:
  std::vector<std::array<SimplexId, 2>> edges_;
  std::vector<std::array<SimplexId, 3>> triangles_;
  std::array<std::vector<std::vector<SimplexId>>, kNumRelations> rows_;
};

}  // namespace actopo::testing

#endif  // ACTOPO_SERVER_CORE_TESTING_ORACLE_H_
