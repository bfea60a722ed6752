#include "server/results/series.h"

#include <chrono>

#include "absl/strings/str_cat.h"

namespace actopo {
namespace {

using Json = nlohmann::ordered_json;

double SecondsSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

// A list of lists from an n x n row-major matrix.
Json Rows(const std::vector<double>& m, int32_t n) {
  Json out = Json::array();
  for (int32_t i = 0; i < n; ++i) {
    out.push_back(std::vector<double>(m.begin() + size_t(i) * n, m.begin() + size_t(i + 1) * n));
  }
  return out;
}

}  // namespace

FieldDiagram ToFieldDiagram(std::string field, const PersistenceDiagramResult& diagram,
                            std::span<const double> values, const DistanceParameters& parameters) {
  FieldDiagram out;
  out.field = std::move(field);
  out.threshold = parameters.ThresholdFor(values);
  out.diagram = diagrams::ToDiagram(diagram, out.threshold);
  out.pair_vertex.reserve(diagram.pairs.size());
  out.pair_value.reserve(diagram.pairs.size());
  for (const PersistencePair& p : diagram.pairs) {
    const bool at_death = p.type == 2 && p.finite();
    out.pair_vertex.push_back(at_death ? p.death : p.birth);
    out.pair_value.push_back(at_death ? p.death_value : p.birth_value);
  }
  return out;
}

FieldDistances CompareFieldDiagrams(std::span<const FieldDiagram> diagrams,
                                    const DistanceParameters& parameters,
                                    const diagrams::MatrixOptions& matrix) {
  const auto start = std::chrono::steady_clock::now();
  FieldDistances out;
  out.parameters = parameters;
  std::vector<diagrams::Diagram> compared;
  for (const FieldDiagram& d : diagrams) {
    out.fields.push_back(d.field);
    out.pairs.push_back(d.diagram.size());
    out.thresholds.push_back(d.threshold);
    compared.push_back(d.diagram);
  }
  out.matrix = diagrams::ComputeDistanceMatrix(compared, parameters.options, matrix);
  if (parameters.matching) {
    diagrams::DistanceOptions with_matching = parameters.options;
    with_matching.matching = true;
    const auto [i, j] = *parameters.matching;
    out.matching = diagrams::ComputeDistance(compared[i], compared[j], with_matching).matching;
  }
  out.seconds = SecondsSince(start);
  return out;
}

absl::Status CheckMatchingEntry(const DistanceParameters& parameters, size_t fields) {
  if (!parameters.matching) return absl::OkStatus();
  const auto [i, j] = *parameters.matching;
  if (size_t(i) >= fields || size_t(j) >= fields) {
    return absl::InvalidArgumentError(absl::StrCat("parameters.matching: ", i, ",", j,
                                                   " is outside the list of ", fields, " fields"));
  }
  return absl::OkStatus();
}

Json FieldDistancesJson(const FieldDistances& d) {
  Json out = {{"fields", d.fields},
              {"p", d.parameters.options.p},
              {"essential", d.parameters.options.essential},
              {"wasserstein", Rows(d.matrix.wasserstein, d.matrix.size)},
              {"bottleneck", Rows(d.matrix.bottleneck, d.matrix.size)},
              {"pairs", d.pairs},
              {"thresholds", d.thresholds},
              {"distance_seconds", d.seconds}};
  if (d.parameters.matching) {
    Json type = Json::array(), a = Json::array(), b = Json::array(), cost = Json::array();
    for (const diagrams::PairMatch& m : d.matching) {
      type.push_back(m.type);
      a.push_back(m.pair_a);
      b.push_back(m.pair_b);
      cost.push_back(m.cost);
    }
    out["matching"] = {{"fields", {d.parameters.matching->first, d.parameters.matching->second}},
                       {"type", type},
                       {"pair_a", a},
                       {"pair_b", b},
                       {"cost", cost}};
  }
  return out;
}

FieldTracking TrackFieldDiagrams(std::span<const FieldDiagram> diagrams,
                                 const DistanceParameters& parameters, int threads) {
  const auto start = std::chrono::steady_clock::now();
  FieldTracking out;
  out.parameters = parameters;
  std::vector<diagrams::Diagram> steps;
  for (const FieldDiagram& d : diagrams) {
    out.fields.push_back(d.field);
    steps.push_back(d.diagram);
  }
  out.tracking = diagrams::TrackPairs(steps, parameters.options, threads);
  out.seconds = SecondsSince(start);
  return out;
}

Json FieldTrackingJson(const FieldTracking& t) {
  std::vector<int64_t> by_type(diagrams::kPairTypes, 0);
  int64_t links = 0, longest = 0;
  for (const diagrams::Trajectory& trajectory : t.tracking.trajectories) {
    ++by_type[trajectory.type];
    links += int64_t(trajectory.costs.size());
    longest = std::max(longest, int64_t(trajectory.pairs.size()));
  }
  Json step = Json::array(), step_by_type = Json::array();
  for (const diagrams::Distance& d : t.tracking.steps) {
    step.push_back(d.wasserstein);
    step_by_type.push_back(d.wasserstein_by_type);
  }
  return {{"fields", t.fields},
          {"p", t.parameters.options.p},
          {"trajectories", t.tracking.trajectories.size()},
          {"trajectories_by_type", by_type},
          {"links", links},
          {"longest", longest},
          {"step_wasserstein", step},
          {"step_wasserstein_by_type", step_by_type},
          {"tracking_seconds", t.seconds}};
}

io::PolyData TrackingPolyData(const FieldTracking& t, std::span<const FieldDiagram> diagrams,
                              std::span<const double> points) {
  io::PolyData out;
  std::vector<int32_t> step, type, vertex, component, matching, length;
  std::vector<double> scalar, cost;
  constexpr int32_t kCriticalType[] = {0, 1, 3};  // a pair's extremum side, by pair type
  for (size_t c = 0; c < t.tracking.trajectories.size(); ++c) {
    const diagrams::Trajectory& trajectory = t.tracking.trajectories[c];
    const int32_t first = int32_t(step.size());
    for (size_t k = 0; k < trajectory.pairs.size(); ++k) {
      const FieldDiagram& field = diagrams[trajectory.first_step + k];
      const SimplexId v = field.pair_vertex[trajectory.pairs[k]];
      out.points.insert(out.points.end(), points.begin() + 3 * size_t(v),
                        points.begin() + 3 * size_t(v) + 3);
      step.push_back(trajectory.first_step + int32_t(k));
      type.push_back(kCriticalType[trajectory.type]);
      vertex.push_back(v);
      scalar.push_back(field.pair_value[trajectory.pairs[k]]);
    }
    for (size_t k = 0; k < trajectory.costs.size(); ++k) {
      out.line_offsets.push_back(int32_t(out.line_connectivity.size()));
      out.line_connectivity.push_back(first + int32_t(k));
      out.line_connectivity.push_back(first + int32_t(k) + 1);
      component.push_back(int32_t(c));
      matching.push_back(int32_t(k));
      cost.push_back(trajectory.costs[k]);
      length.push_back(int32_t(trajectory.costs.size()));
    }
  }
  out.line_offsets.push_back(int32_t(out.line_connectivity.size()));
  if (component.empty()) out.line_offsets.clear();  // no lines: an empty output
  out.point_arrays = {{"TimeStep", std::move(step)},
                      {"CriticalType", std::move(type)},
                      {"Scalar", std::move(scalar)},
                      {"VertexId", std::move(vertex)}};
  out.cell_arrays = {{"ConnectedComponentId", std::move(component)},
                     {"MatchingIdentifier", std::move(matching)},
                     {"Cost", std::move(cost)},
                     {"ComponentLength", std::move(length)}};
  return out;
}

}  // namespace actopo
