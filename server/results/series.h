// The algorithms that compare fields (a series' steps or an ensemble's members), as actopo-bench
// and the service report them. Each field's persistence diagram comes first (the
// persistence-diagram algorithm, field by field over one structure); then
//   - diagram-distance: the distances between every two diagrams (server/diagrams/distance.h);
//   - tracking: the pairs of consecutive fields matched and chained into trajectories
//     (server/diagrams/tracking.h), written for ParaView as TTK's tracking output.
//
//   std::vector<FieldDiagram> diagrams;   // per field: ToFieldDiagram(name, result, values, ...)
//   FieldDistances d = CompareFieldDiagrams(diagrams, input.distance, {.threads = 2});
//   nlohmann::ordered_json result = FieldDistancesJson(d);
//   FieldTracking t = TrackFieldDiagrams(diagrams, input.distance, 2);
//   io::PolyData lines = TrackingPolyData(t, diagrams, mesh.points);
#ifndef ACTOPO_SERVER_RESULTS_SERIES_H_
#define ACTOPO_SERVER_RESULTS_SERIES_H_

#include <string>
#include <vector>

#include "nlohmann/json.hpp"
#include "server/diagrams/distance.h"
#include "server/diagrams/tracking.h"
#include "server/io/vtk_writer.h"
#include "server/results/run_algorithm.h"

namespace actopo {

// One field's diagram as the comparisons see it, with what outputs say of each pair: the
// vertex that places it (its extremum side: the birth vertex, a minimum, for type 0; the
// death vertex, a maximum, for type 2; the birth vertex for type 1) and the scalar there.
struct FieldDiagram {
  std::string field;
  diagrams::Diagram diagram;
  double threshold = 0;                // the absolute persistence threshold applied to it
  std::vector<SimplexId> pair_vertex;  // by pair index in the field's diagram (input ids)
  std::vector<double> pair_value;
};

// A field's diagram with `parameters`' threshold applied (relative: to the field's range).
FieldDiagram ToFieldDiagram(std::string field, const PersistenceDiagramResult& diagram,
                            std::span<const double> values, const DistanceParameters& parameters);

// parameters.matching's entry is a pair of positions in a list of `fields` fields: an error
// naming the parameter otherwise.
absl::Status CheckMatchingEntry(const DistanceParameters& parameters, size_t fields);

struct FieldDistances {
  std::vector<std::string> fields;
  std::vector<int64_t> pairs;       // pairs compared per field
  std::vector<double> thresholds;   // absolute threshold per field
  diagrams::DistanceMatrix matrix;  // Wasserstein-p and bottleneck, n x n
  DistanceParameters parameters;
  // With parameters.matching (I, J): the optimal Wasserstein-p matching of fields I and J,
  // pairs named by their index in each field's diagram (its PairIdentifier).
  std::vector<diagrams::PairMatch> matching;
  double seconds = 0;  // the distances alone, the diagrams not included
};

// Every entry of the matrix; stops early when `matrix.stopped` says so (the caller reports
// why: the entries left are 0).
FieldDistances CompareFieldDiagrams(std::span<const FieldDiagram> diagrams,
                                    const DistanceParameters& parameters,
                                    const diagrams::MatrixOptions& matrix);

// {"fields": [...], "p": P, "essential": bool, "wasserstein": n x n, "bottleneck": n x n,
//  "pairs": [...], "thresholds": [...], "distance_seconds": s}, and with a matching asked for
//  "matching": {"fields": [I, J], "type": [...], "pair_a": [...], "pair_b": [...], "cost": [...]}
//  (a pair sent to the diagonal has -1 on the other side).
nlohmann::ordered_json FieldDistancesJson(const FieldDistances& distances);

struct FieldTracking {
  std::vector<std::string> fields;  // the steps, in time order
  diagrams::Tracking tracking;
  DistanceParameters parameters;
  double seconds = 0;  // the matchings and chains alone
};

FieldTracking TrackFieldDiagrams(std::span<const FieldDiagram> diagrams,
                                 const DistanceParameters& parameters, int threads);

// {"fields": [...], "p": P, "trajectories": count, "trajectories_by_type": [n0, n1, n2],
//  "links": count, "longest": steps of the longest trajectory, "step_wasserstein": [W_p of
//  steps (t, t + 1)], "step_wasserstein_by_type": [[per type] per step], "tracking_seconds": s}.
nlohmann::ordered_json FieldTrackingJson(const FieldTracking& tracking);

// TTK's tracking output: a point per tracked pair and step at its vertex (`points`: x, y, z by
// input vertex id), a line cell per link. Point arrays TimeStep (the step's index), CriticalType
// (0 minimum, 1 1-saddle, 3 maximum: the pair's extremum side), Scalar, VertexId; cell arrays
// ConnectedComponentId (the trajectory), MatchingIdentifier (the link's position in its
// trajectory), Cost (the link's ground cost), ComponentLength (the trajectory's links).
io::PolyData TrackingPolyData(const FieldTracking& tracking, std::span<const FieldDiagram> diagrams,
                              std::span<const double> points);

}  // namespace actopo

#endif  // ACTOPO_SERVER_RESULTS_SERIES_H_
