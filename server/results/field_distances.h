// diagram-distance over a list of fields: each field's persistence diagram (the
// persistence-diagram algorithm, run field by field over one structure), then the distances
// between every two diagrams (server/diagrams), as actopo-bench and the service report them.
//
//   std::vector<FieldDiagram> diagrams;   // per field: name, ToDiagram(result, threshold)
//   FieldDistances d = CompareFieldDiagrams(std::move(diagrams), input.distance, {.threads = 2});
//   nlohmann::ordered_json result = FieldDistancesJson(d);
#ifndef ACTOPO_SERVER_RESULTS_FIELD_DISTANCES_H_
#define ACTOPO_SERVER_RESULTS_FIELD_DISTANCES_H_

#include <string>
#include <vector>

#include "nlohmann/json.hpp"
#include "server/diagrams/distance.h"
#include "server/results/run_algorithm.h"

namespace actopo {

// One field's diagram as the distances compare it.
struct FieldDiagram {
  std::string field;
  diagrams::Diagram diagram;
  double threshold = 0;  // the absolute persistence threshold applied to it
};

// A field's diagram with `parameters`' threshold applied (relative: to the field's range).
FieldDiagram ToFieldDiagram(std::string field, const PersistenceDiagramResult& diagram,
                            std::span<const double> values, const DistanceParameters& parameters);

struct FieldDistances {
  std::vector<std::string> fields;
  std::vector<int64_t> pairs;       // pairs compared per field
  std::vector<double> thresholds;   // absolute threshold per field
  diagrams::DistanceMatrix matrix;  // Wasserstein-p and bottleneck, n x n
  DistanceParameters parameters;
  double seconds = 0;  // the distances alone, the diagrams not included
};

// Every entry of the matrix; stops early when `matrix.stopped` says so (the caller reports
// why: the entries left are 0).
FieldDistances CompareFieldDiagrams(std::vector<FieldDiagram> diagrams,
                                    const DistanceParameters& parameters,
                                    const diagrams::MatrixOptions& matrix);

// {"fields": [...], "p": P, "wasserstein": n x n, "bottleneck": n x n, "pairs": [...],
//  "thresholds": [...], "essential": bool, "distance_seconds": s}.
nlohmann::ordered_json FieldDistancesJson(const FieldDistances& distances);

}  // namespace actopo

#endif  // ACTOPO_SERVER_RESULTS_FIELD_DISTANCES_H_
