// critical-points: TTK's ScalarFieldCriticalPoints in 3D (SEMANTICS.md).
//
// For each vertex, the connected components of the lower and of the upper part of its link
// (two link vertices are connected when they are two other vertices of a tetrahedron of its
// star, both lower or both upper) give its type: (0,1) minimum, (1,0) maximum, (1,1) regular,
// (2,1) 1-saddle, (1,2) 2-saddle, anything else degenerate. With the default boundary rule of
// TTK >= 1.1, a boundary vertex with (1,1) is a 1-saddle if some upper neighbour is on the
// boundary and no lower one is, a 2-saddle in the reverse case.
//
//   std::vector<SimplexId> order = VertexOrder(*topology, scalars);
//   ASSIGN_OR_RETURN(CriticalPointsResult r,
//                    RunCriticalPoints(*structure, order, {}, {.consumers = 2}));
#ifndef ACTOPO_SERVER_ALGORITHMS_CRITICAL_POINTS_H_
#define ACTOPO_SERVER_ALGORITHMS_CRITICAL_POINTS_H_

#include <array>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "server/algorithms/consumers.h"
#include "server/core/relation.h"
#include "server/core/structures.h"

namespace actopo {

// TTK's CriticalType codes.
enum class CriticalType : int8_t {
  kMinimum = 0,
  kSaddle1 = 1,
  kSaddle2 = 2,
  kMaximum = 3,
  kDegenerate = 4,
  kRegular = 5,
};

enum class BoundaryRule : uint8_t {
  kTtk,   // TTK >= 1.1: boundary (1,1) vertices may be saddles (the default)
  kNone,  // the link alone decides
};

struct CriticalPointsOptions {
  BoundaryRule boundary_rule = BoundaryRule::kTtk;
};

struct CriticalPoint {
  SimplexId vertex = 0;  // input id
  CriticalType type = CriticalType::kRegular;
  bool on_boundary = false;
};

struct CriticalPointsResult {
  std::vector<CriticalPoint> points;  // critical vertices, ascending input id
  // minimum, saddle1, saddle2, maximum, degenerate (indexed by CriticalType)
  std::array<int64_t, 5> counts{};

  // SHA-256 of "<vertex id> <type>\n" per critical vertex in ascending id.
  std::string VerticesDigest() const;
};

// VT (the star, whose other vertices are the link's, numbered as met) and VB (the boundary
// rule). No VV: looking each star vertex up in it cost a search per tetrahedron corner, and
// computing it a block scan of its own.
RelationSet CriticalPointsDeclared();
// What it reads for every vertex: VT. A vertex's own boundary flag comes from the link edges it
// counts anyway; VB is read only for the neighbours of boundary vertices.
RelationSet CriticalPointsSwept();

// `order` is VertexOrder() of the scalar field (by internal id). Defined for the explicit,
// compact and actopo structures.
template <TopologicalStructure Structure>
absl::StatusOr<CriticalPointsResult> RunCriticalPoints(Structure& structure,
                                                       std::span<const SimplexId> order,
                                                       const CriticalPointsOptions& options,
                                                       const RunContext& context);

}  // namespace actopo

#endif  // ACTOPO_SERVER_ALGORITHMS_CRITICAL_POINTS_H_
