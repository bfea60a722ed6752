#include "server/results/field_distances.h"

#include <chrono>

namespace actopo {

FieldDiagram ToFieldDiagram(std::string field, const PersistenceDiagramResult& diagram,
                            std::span<const double> values, const DistanceParameters& parameters) {
  const double threshold = parameters.ThresholdFor(values);
  return {std::move(field), diagrams::ToDiagram(diagram, threshold), threshold};
}

FieldDistances CompareFieldDiagrams(std::vector<FieldDiagram> diagrams,
                                    const DistanceParameters& parameters,
                                    const diagrams::MatrixOptions& matrix) {
  const auto start = std::chrono::steady_clock::now();
  FieldDistances out;
  out.parameters = parameters;
  std::vector<diagrams::Diagram> compared;
  for (FieldDiagram& d : diagrams) {
    out.fields.push_back(d.field);
    out.pairs.push_back(d.diagram.size());
    out.thresholds.push_back(d.threshold);
    compared.push_back(std::move(d.diagram));
  }
  out.matrix = diagrams::ComputeDistanceMatrix(compared, parameters.options, matrix);
  out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return out;
}

nlohmann::ordered_json FieldDistancesJson(const FieldDistances& d) {
  using Json = nlohmann::ordered_json;
  const int32_t n = d.matrix.size;
  auto rows = [&](const std::vector<double>& m) {
    Json out = Json::array();
    for (int32_t i = 0; i < n; ++i) {
      out.push_back(std::vector<double>(m.begin() + size_t(i) * n, m.begin() + size_t(i + 1) * n));
    }
    return out;
  };
  return {{"fields", d.fields},
          {"p", d.parameters.options.p},
          {"essential", d.parameters.options.essential},
          {"wasserstein", rows(d.matrix.wasserstein)},
          {"bottleneck", rows(d.matrix.bottleneck)},
          {"pairs", d.pairs},
          {"thresholds", d.thresholds},
          {"distance_seconds", d.seconds}};
}

}  // namespace actopo
