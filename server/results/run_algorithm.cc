#include "server/results/run_algorithm.h"

#include <algorithm>
#include <chrono>
#include <cmath>

#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_split.h"
#include "server/core/actopo_structure.h"
#include "server/core/compact_structure.h"
#include "server/core/explicit_structure.h"
#include "server/core/process_memory.h"
#include "server/core/status_macros.h"
#include "server/core/structures.h"

namespace actopo {
namespace {

using Json = nlohmann::ordered_json;

Json TopoRelationsJson(const TopoRelationsResult& r) {
  Json totals = Json::object();
  for (Relation rel : TopoRelationsSweeps(r.all)) {
    totals[std::string(RelationName(rel))] = r.totals[Index(rel)];
  }
  return {{"relations", r.all ? "all" : "ttk"},
          {"relation_totals", totals},
          {"checksum", r.checksum_hex()}};
}

Json CriticalPointsJson(const CriticalPointsResult& r, bool digests) {
  const auto count = [&](CriticalType t) { return r.counts[int(t)]; };
  Json j = {{"counts",
             {{"minimum", count(CriticalType::kMinimum)},
              {"saddle1", count(CriticalType::kSaddle1)},
              {"saddle2", count(CriticalType::kSaddle2)},
              {"degenerate", count(CriticalType::kDegenerate)},
              {"maximum", count(CriticalType::kMaximum)}}}};
  if (digests) j["vertices_sha256"] = r.VerticesDigest();
  return j;
}

Json DiscreteGradientJson(const DiscreteGradientResult& r, const Topology& topology, bool digests) {
  Json j = {{"critical_cells", r.critical_cells}, {"pairs_count", r.pairs}};
  if (digests) {
    j["critical_cells_sha256"] = r.CriticalCellsDigest(topology);
    j["pairs_sha256"] = r.PairsDigest(topology);
  }
  return j;
}

Json MorseSmaleJson(const MorseSmaleResult& r, bool digests) {
  auto unlabelled = [](const std::vector<SimplexId>& labels) {
    return std::count(labels.begin(), labels.end(), -1);
  };
  int64_t minima = 0, maxima = 0;
  for (int64_t s : r.minimum_sizes) minima += s;
  for (int64_t s : r.maximum_sizes) maxima += s;
  Json j = {{"critical_cells", r.gradient.critical_cells},
            {"separatrices",
             {{"descending", r.CountSeparatrices(SeparatrixType::kDescending)},
              {"ascending", r.CountSeparatrices(SeparatrixType::kAscending)},
              {"saddle_connectors", r.CountSeparatrices(SeparatrixType::kSaddleConnector)},
              {"segments", r.Segments()}}},
            {"regions",
             {{"descending", MorseSmaleResult::Regions(r.descending)},
              {"ascending", MorseSmaleResult::Regions(r.ascending)},
              {"morse_smale", MorseSmaleResult::Regions(r.morse_smale)}}},
            {"manifold_size_sum", {{"minima", minima}, {"maxima", maxima}}},
            {"unlabelled_vertices",
             {{"descending", unlabelled(r.descending)},
              {"ascending", unlabelled(r.ascending)},
              {"morse_smale", unlabelled(r.morse_smale)}}}};
  if (digests) {
    j["segmentation_sha256"] = {
        {"descending", MorseSmaleResult::SegmentationDigest(r.descending)},
        {"ascending", MorseSmaleResult::SegmentationDigest(r.ascending)},
        {"morse_smale", MorseSmaleResult::SegmentationDigest(r.morse_smale)}};
  }
  return j;
}

Json PersistenceDiagramJson(const PersistenceDiagramResult& r, bool digests) {
  Json counts = Json::object();
  for (int k = 0; k < 3; ++k) {
    if (r.finite[k] > 0) counts[std::to_string(k)] = r.finite[k];
    if (r.infinite[k] > 0) counts[absl::StrCat(k, "_infinite")] = r.infinite[k];
  }
  Json j = {{"pairs", r.pairs.size()},
            {"counts_by_type", counts},
            {"critical_cells", r.gradient.critical_cells},
            {"max_persistence", r.MaxPersistence()}};
  if (digests) j["pairs_sha256"] = r.PairsDigest();
  return j;
}

Json SimplificationJson(const SimplificationResult& r, bool digests) {
  const SimplificationStats& s = r.stats;
  Json j = {{"backend", r.legacy ? "legacy" : "lts"},
            {"threshold", r.threshold},
            {"pairs", r.diagram.pairs.size()},
            {"kept_pairs", s.kept_pairs},
            {"removed_pairs", s.removed_pairs},
            {"constraints", s.constraints},
            {"removed_maxima", s.removed_maxima},
            {"removed_minima", s.removed_minima},
            {"changed_values", s.changed_values},
            {"minima", s.minima},
            {"maxima", s.maxima}};
  if (digests) {
    j["scalars_sha256"] = r.ScalarsDigest();
    j["order_sha256"] = r.OrderDigest();
  }
  if (r.legacy) j["sweeps"] = s.sweeps;
  return j;
}

Json TreeJson(const TreeResult& r, bool digests) {
  Json types = Json::object();
  for (size_t t = 0; t < r.counts.size(); ++t) {
    if (r.counts[t] > 0) types[std::to_string(t)] = r.counts[t];
  }
  Json j = {{"tree", TreeTypeName(r.type)},
            {"nodes", r.nodes.size()},
            {"arcs", r.arcs.size()},
            {"components", r.component_node_begin.size() - 1},
            {"critical_types", types}};
  if (digests) {
    j["nodes_sha256"] = r.NodesDigest();
    j["arcs_sha256"] = r.ArcsDigest();
    j["segmentation_sha256"] = r.SegmentationDigest();
  }
  return j;
}

// A threshold parameter: a finite number.
absl::StatusOr<double> ParseThreshold(const std::string& name, const std::string& value) {
  double t = 0;
  if (!absl::SimpleAtod(value, &t) || !std::isfinite(t)) {
    return absl::InvalidArgumentError(
        absl::StrCat("parameters.", name, ": '", value, "' is not a number"));
  }
  return t;
}

// The default threshold of topological-simplification: 1% of the field's range.
constexpr SimplificationOptions kDefaultSimplification{.threshold = 0.01, .relative = true};

// One of diagram-distance's parameters (ApplyParameters).
absl::Status ApplyDistanceParameter(const std::string& name, const std::string& value,
                                    DistanceParameters& distance) {
  if (name == "p") {
    double p = 0;
    if (!absl::SimpleAtod(value, &p)) {
      return absl::InvalidArgumentError(
          absl::StrCat("parameters.p: '", value, "' is not a number"));
    }
    distance.options.p = p;
    if (absl::Status s = diagrams::ValidateDistanceOptions(distance.options); !s.ok()) {
      return absl::InvalidArgumentError(absl::StrCat("parameters.", s.message()));
    }
    return absl::OkStatus();
  }
  if (name == "persistence_threshold" || name == "relative_threshold") {
    ASSIGN_OR_RETURN(const double t, ParseThreshold(name, value));
    const bool relative = name == "relative_threshold";
    if (t < 0 || (relative && t > 1)) {
      return absl::InvalidArgumentError(absl::StrCat(
          "parameters.", name, ": ", value, " is outside ", relative ? "[0, 1]" : "[0, inf)"));
    }
    distance.threshold = t;
    distance.relative = relative;
    return absl::OkStatus();
  }
  if (name == "essential") {
    if (value != "true" && value != "false") {
      return absl::InvalidArgumentError(
          absl::StrCat("parameters.essential: '", value, "' is not true or false"));
    }
    distance.options.essential = value == "true";
    return absl::OkStatus();
  }
  if (name == "matching") {
    const std::vector<std::string> parts = absl::StrSplit(value, ',');
    int32_t i = -1, j = -1;
    if (parts.size() != 2 || !absl::SimpleAtoi(parts[0], &i) || !absl::SimpleAtoi(parts[1], &j) ||
        i < 0 || j < 0) {
      return absl::InvalidArgumentError(absl::StrCat(
          "parameters.matching: '", value, "' is not two field positions 'I,J' (from 0)"));
    }
    distance.matching = std::make_pair(i, j);
    return absl::OkStatus();
  }
  return absl::InvalidArgumentError(absl::StrCat(
      "parameters: unknown parameter '", name,
      "'; available: p, persistence_threshold, relative_threshold, essential, matching"));
}

std::span<const uint8_t> InputCornersOf(const AlgorithmInput& input) {
  if (input.input_corners == nullptr) return {};  // RunMorseSmale names the mismatch
  return *input.input_corners;
}

}  // namespace

double DistanceParameters::ThresholdFor(std::span<const double> values) const {
  if (!relative || values.empty()) return threshold;
  const auto [lo, hi] = std::minmax_element(values.begin(), values.end());
  return threshold * (*hi - *lo);
}

absl::Status ApplyParameters(const std::map<std::string, std::string>& parameters,
                             AlgorithmInput& input) {
  if (parameters.contains("persistence_threshold") && parameters.contains("relative_threshold")) {
    return absl::InvalidArgumentError(
        "parameters: give persistence_threshold or relative_threshold, not both");
  }
  for (const auto& [name, value] : parameters) {
    if (ComparesFields(input.algorithm)) {
      RETURN_IF_ERROR(ApplyDistanceParameter(name, value, input.distance));
      continue;
    }
    if (name == "boundary_rule" && input.algorithm == Algorithm::kCriticalPoints) {
      if (value == "ttk") {
        input.critical_points.boundary_rule = BoundaryRule::kTtk;
      } else if (value == "none") {
        input.critical_points.boundary_rule = BoundaryRule::kNone;
      } else {
        return absl::InvalidArgumentError(absl::StrCat("parameters.boundary_rule: unknown value '",
                                                       value, "'; available: ttk, none"));
      }
      continue;
    }
    if (name == "relations" && input.algorithm == Algorithm::kTopoRelations) {
      if (value != "ttk" && value != "all") {
        return absl::InvalidArgumentError(
            absl::StrCat("parameters.relations: unknown value '", value, "'; available: ttk, all"));
      }
      input.topo_relations.all = value == "all";
      continue;
    }
    if (name == "embedding" && input.algorithm == Algorithm::kPersistenceDiagram) {
      if (value != "diagram" && value != "domain") {
        return absl::InvalidArgumentError(absl::StrCat("parameters.embedding: unknown value '",
                                                       value, "'; available: diagram, domain"));
      }
      input.embed_diagram_in_domain = value == "domain";
      continue;
    }
    if (name == "tree" && input.algorithm == Algorithm::kMergeTree) {
      if (value != "join" && value != "split") {
        return absl::InvalidArgumentError(
            absl::StrCat("parameters.tree: unknown value '", value, "'; available: join, split"));
      }
      input.tree = value == "join" ? TreeType::kJoin : TreeType::kSplit;
      continue;
    }
    const bool simplifies = input.algorithm == Algorithm::kTopologicalSimplification ||
                            input.algorithm == Algorithm::kMorseSmale ||
                            input.algorithm == Algorithm::kMergeTree ||
                            input.algorithm == Algorithm::kContourTree;
    if ((name == "persistence_threshold" || name == "relative_threshold") && simplifies) {
      ASSIGN_OR_RETURN(const double t, ParseThreshold(name, value));
      const SimplificationOptions options{.threshold = t, .relative = name == "relative_threshold"};
      if (absl::Status s = ValidateSimplificationOptions(options); !s.ok()) {
        return absl::InvalidArgumentError(absl::StrCat("parameters.", name, ": ", s.message()));
      }
      input.simplification = options;
      continue;
    }
    if (name == "backend" && simplifies) {
      if (value != "lts" && value != "legacy") {
        return absl::InvalidArgumentError(absl::StrCat("parameters.backend: unknown value '", value,
                                                       "'; available: lts, legacy"));
      }
      continue;  // applied below, once the threshold is known
    }
    return absl::InvalidArgumentError(absl::StrCat("parameters: unknown parameter '", name,
                                                   "' for ",
                                                   std::string(AlgorithmName(input.algorithm))));
  }
  if (const auto backend = parameters.find("backend"); backend != parameters.end()) {
    if (!input.simplification && input.algorithm != Algorithm::kTopologicalSimplification) {
      return absl::InvalidArgumentError(
          absl::StrCat("parameters.backend: ", std::string(AlgorithmName(input.algorithm)),
                       " simplifies only with persistence_threshold or relative_threshold"));
    }
    if (!input.simplification) input.simplification = kDefaultSimplification;
    input.simplification->legacy = backend->second == "legacy";
  }
  return absl::OkStatus();
}

bool NeedsFaces(const AlgorithmInput& input) {
  return NeedsFaces(input.algorithm) || input.simplification.has_value();
}

bool NeedsScalarValues(const AlgorithmInput& input) {
  return NeedsScalarValues(input.algorithm) || input.simplification.has_value();
}

RelationSet DeclaredRelations(const AlgorithmInput& input) {
  RelationSet relations = DeclaredRelations(input.algorithm);
  if (input.simplification) relations = relations | TopologicalSimplificationDeclared();
  return relations;
}

RelationSet SweptRelations(const AlgorithmInput& input) {
  RelationSet relations = SweptRelations(input.algorithm);
  if (input.simplification) relations = relations | TopologicalSimplificationSwept();
  return relations;
}

template <TopologicalStructure Structure>
absl::StatusOr<AlgorithmOutcome> RunAlgorithm(Structure& structure, const AlgorithmInput& in,
                                              const RunContext& context) {
  const auto start = std::chrono::steady_clock::now();
  // The structure records into the run's trace while the algorithm runs.
  struct Recording {
    Structure& structure;
    explicit Recording(Structure& s, const std::shared_ptr<Trace>& trace) : structure(s) {
      if constexpr (kTraces<Structure>) s.SetTrace(trace);
    }
    ~Recording() {
      if constexpr (kTraces<Structure>) structure.SetTrace(nullptr);
    }
  } recording(structure, context.trace);
  if (NeedsFaces(in) && !structure.topology().has_faces()) {
    return absl::FailedPreconditionError(
        absl::StrCat("algorithm: ", std::string(AlgorithmName(in.algorithm)),
                     " needs edges and triangles, and the topology was built without them"));
  }
  Trace::Scope span(context.trace.get(), AlgorithmName(in.algorithm).data(), "phase");
  AlgorithmOutcome out;
  switch (in.algorithm) {
    case Algorithm::kTopoRelations: {
      ASSIGN_OR_RETURN(out.result, RunTopoRelations(structure, context, in.topo_relations));
      break;
    }
    case Algorithm::kCriticalPoints: {
      ASSIGN_OR_RETURN(out.result,
                       RunCriticalPoints(structure, in.order, in.critical_points, context));
      break;
    }
    case Algorithm::kDiscreteGradient: {
      // The job reports counts, critical cells and digests, which the persistence arrays give
      // without the other three (GradientArrays).
      ASSIGN_OR_RETURN(out.result, RunDiscreteGradient(structure, in.order, context,
                                                       GradientArrays::kPersistence));
      break;
    }
    case Algorithm::kMorseSmale: {
      if (!in.simplification) {
        ASSIGN_OR_RETURN(out.result,
                         RunMorseSmale(structure, in.order, InputCornersOf(in), context));
        break;
      }
      // As a TTK user chains the filters: simplify, then the complex of the simplified field
      // with its order (TTK's "<field>_Order").
      SimplifiedMorseSmaleResult r;
      ASSIGN_OR_RETURN(r.simplification,
                       RunTopologicalSimplification(structure, in.order, in.scalars,
                                                    *in.simplification, context.Slice(0, 0.5)));
      // The complex's gradient: the diagram's, paired again where LTS moved the order (a few
      // percent of the vertices); legacy sweeps may move every vertex.
      std::optional<DiscreteGradientResult> gradient;
      if (!r.simplification.legacy) {
        ASSIGN_OR_RETURN(gradient, UpdateDiscreteGradient(
                                       structure, std::move(r.simplification.diagram.gradient),
                                       r.simplification.internal_order, r.simplification.reordered,
                                       context.Slice(0.5, 0.75), r.simplification.changed_stars));
      }
      ASSIGN_OR_RETURN(r.morse_smale,
                       RunMorseSmale(structure, r.simplification.internal_order, InputCornersOf(in),
                                     context.Slice(0.5, 1), std::move(gradient)));
      out.result = std::move(r);
      break;
    }
    case Algorithm::kPersistenceDiagram:
    case Algorithm::kDiagramDistance:
    case Algorithm::kTracking: {  // per field, the diagram; compared by the caller
      ASSIGN_OR_RETURN(PersistenceDiagramResult diagram,
                       RunPersistenceDiagram(structure, in.order, in.scalars, context));
      diagram.embed_in_domain = in.embed_diagram_in_domain;
      out.result = std::move(diagram);
      break;
    }
    case Algorithm::kMergeTree:
    case Algorithm::kContourTree: {
      const TreeType type = in.algorithm == Algorithm::kContourTree ? TreeType::kContour : in.tree;
      if (!in.simplification) {
        ASSIGN_OR_RETURN(out.result, RunTree(structure, in.order, type, context));
        break;
      }
      // As a TTK user chains the filters: simplify, then the tree of the simplified field with
      // its order (TTK's "<field>_Order").
      SimplifiedTreeResult r;
      ASSIGN_OR_RETURN(r.simplification,
                       RunTopologicalSimplification(structure, in.order, in.scalars,
                                                    *in.simplification, context.Slice(0, 0.8)));
      r.simplification.diagram.gradient = {};  // the tree reads the order alone
      ASSIGN_OR_RETURN(
          r.tree, RunTree(structure, r.simplification.internal_order, type, context.Slice(0.8, 1)));
      out.result = std::move(r);
      break;
    }
    case Algorithm::kTopologicalSimplification: {
      ASSIGN_OR_RETURN(out.result,
                       RunTopologicalSimplification(
                           structure, in.order, in.scalars,
                           in.simplification.value_or(kDefaultSimplification), context));
      break;
    }
  }
  out.run_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  out.peak_rss_after_run = PeakRssBytes();
  return out;
}

#define ACTOPO_INSTANTIATE(S)                                                       \
  template absl::StatusOr<AlgorithmOutcome> RunAlgorithm(S&, const AlgorithmInput&, \
                                                         const RunContext&);
ACTOPO_FOR_EACH_STRUCTURE(ACTOPO_INSTANTIATE)
#undef ACTOPO_INSTANTIATE

Json Summarize(const AlgorithmResult& result, const Topology& topology,
               const SummaryOptions& options) {
  const bool digests = options.digests;
  return std::visit(
      [&](const auto& r) -> Json {
        using T = std::decay_t<decltype(r)>;
        if constexpr (std::is_same_v<T, TopoRelationsResult>) return TopoRelationsJson(r);
        if constexpr (std::is_same_v<T, CriticalPointsResult>) {
          return CriticalPointsJson(r, digests);
        }
        if constexpr (std::is_same_v<T, DiscreteGradientResult>) {
          return DiscreteGradientJson(r, topology, digests);
        }
        if constexpr (std::is_same_v<T, MorseSmaleResult>) return MorseSmaleJson(r, digests);
        if constexpr (std::is_same_v<T, PersistenceDiagramResult>) {
          return PersistenceDiagramJson(r, digests);
        }
        if constexpr (std::is_same_v<T, SimplificationResult>) {
          return SimplificationJson(r, digests);
        }
        if constexpr (std::is_same_v<T, TreeResult>) return TreeJson(r, digests);
        if constexpr (std::is_same_v<T, SimplifiedTreeResult>) {
          Json j = TreeJson(r.tree, digests);
          j["simplification"] = SimplificationJson(r.simplification, digests);
          return j;
        }
        if constexpr (std::is_same_v<T, SimplifiedMorseSmaleResult>) {
          Json j = MorseSmaleJson(r.morse_smale, digests);
          j["simplification"] = SimplificationJson(r.simplification, digests);
          return j;
        }
      },
      result);
}

}  // namespace actopo
