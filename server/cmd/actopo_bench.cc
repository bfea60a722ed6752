// actopo-bench: loads a mesh, partitions it, builds a structure and runs one algorithm
// in-process (no gRPC), then prints times, memory, access statistics and the result.
//
//   actopo-bench --mesh ../shared/data/fertility_tet.vtu --algorithm topo-relations
//       --structure compact --json
//   actopo-bench --mesh F.vtu --algorithm morse-smale --structure actopo --trace run.json
//   actopo-bench --mesh F.vtu --algorithm discrete-gradient --digests --json   # TTK-comparable
#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iostream>
#include <map>
#include <optional>

#include "absl/strings/match.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "absl/strings/str_replace.h"
#include "absl/strings/str_split.h"
#include "nlohmann/json.hpp"
#include "server/algorithms/registry.h"
#include "server/algorithms/structure_options.h"
#include "server/algorithms/vertex_order.h"
#include "server/cmd/flags.h"
#include "server/core/actopo_structure.h"
#include "server/core/compact_structure.h"
#include "server/core/explicit_structure.h"
#include "server/core/parallel.h"
#include "server/core/partition.h"
#include "server/core/process_memory.h"
#include "server/core/status_macros.h"
#include "server/core/structures.h"
#include "server/core/topology.h"
#include "server/core/trace.h"
#include "server/io/samples.h"
#include "server/io/vtk_reader.h"
#include "server/results/result_files.h"
#include "server/results/run_algorithm.h"
#include "server/results/series.h"

namespace actopo {
namespace {

using Json = nlohmann::ordered_json;
using Clock = std::chrono::steady_clock;

struct BenchOptions {
  std::string mesh;
  std::string sample;
  std::string scalar;
  std::string scalars;  // many fields: "F1,F2,..." or "all"
  std::string algorithm = "topo-relations";
  std::string structure = "compact";
  int consumers = 0;  // 0: DefaultThreadPlan
  int producers = 0;
  std::string prefetch = "auto";
  std::string precompute = "auto";
  std::string miss_policy = "consumer";
  std::string producer_priority = "auto";
  double buffer_ratio = 0.2;
  int block_size = 1000;
  std::string block_labels;
  std::string boundary_rule = "ttk";
  std::string persistence_threshold, relative_threshold;  // as given, parsed by ApplyParameters
  std::string embedding;
  std::string tree;        // merge-tree: join or split
  std::string backend;     // simplification: lts or legacy
  std::string relations;   // topo-relations: ttk or all
  std::string p;           // diagram-distance: the Wasserstein order
  std::string matching;    // diagram-distance: "I,J", the entry whose matching to report
  bool essential = false;  // diagram-distance: match the infinite pairs too
  std::string output;
  std::string trace;  // Chrome trace-event JSON file
  int threads = 0;
  bool json = false;
  bool digests = false;  // the result's *_sha256 keys
};

// Process start as near as a program can take it: `total` is what a user waits for.
const Clock::time_point kProcessStart = Clock::now();

double Seconds(Clock::time_point since) {
  return std::chrono::duration<double>(Clock::now() - since).count();
}

// A phase [start, now) on the main thread's row of the trace.
void Phase(const std::shared_ptr<Trace>& trace, const char* name, Clock::time_point start) {
  if (trace) trace->Span(name, "phase", start, Clock::now());
}

absl::Status Validate(const BenchOptions& o) {
  if (o.mesh.empty() == o.sample.empty()) {
    return absl::InvalidArgumentError("give exactly one of --mesh PATH or --sample NAME");
  }
  if (o.boundary_rule != "ttk" && o.boundary_rule != "none") {
    return absl::InvalidArgumentError(absl::StrCat("--boundary-rule: unknown rule '",
                                                   o.boundary_rule, "'; available: ttk, none"));
  }
  if (o.block_size < 1) {
    return absl::InvalidArgumentError(
        absl::StrCat("--block-size: ", o.block_size, " must be at least 1"));
  }
  return absl::OkStatus();
}

// One field's run: its vertex order, the algorithm, the summary (and --output files).
struct FieldOutput {
  std::string field;
  double order_s = 0, run_s = 0;
  double results_s = 0;            // the summary (digests with --digests), --output files
  int64_t peak_rss_after_run = 0;  // before result digests and files, which can be large
  std::vector<std::string> files;  // written with --output
  Json result;
};

// The runs over every field on one structure, built once.
struct RunOutput {
  double preprocess_s = 0;
  std::vector<FieldOutput> fields;
  Json engine_detail = Json::object();  // actopo only
  AccessStats access;
  MemoryStats memory;
};

// What changes from field to field, for the structure-specific runners below.
struct FieldRuns {
  size_t count = 0;
  // The algorithm's input for field i (its vertex order, timed into `order_s`).
  std::function<absl::StatusOr<AlgorithmInput>(size_t i, double& order_s)> input;
  // Where field i's --output files go, or null.
  std::function<const ResultContext*(size_t i)> files;
  // Called with each field's outcome before its summary (diagram-distance keeps the diagrams).
  std::function<void(size_t i, const AlgorithmOutcome&)> keep;
  // Several fields: each one's files are PREFIX_<field>_*, not PREFIX_*.
  bool many = false;
};

// Runs field i's algorithm on `structure` and summarizes it.
template <TopologicalStructure Structure>
absl::StatusOr<FieldOutput> RunAndSummarize(Structure& structure, const AlgorithmInput& input,
                                            const RunContext& context, const BenchOptions& o,
                                            const FieldRuns& runs, size_t i) {
  ASSIGN_OR_RETURN(AlgorithmOutcome outcome, RunAlgorithm(structure, input, context));
  FieldOutput out;
  out.run_s = outcome.run_s;
  out.peak_rss_after_run = outcome.peak_rss_after_run;
  if (runs.keep) runs.keep(i, outcome);
  const auto start = Clock::now();
  out.result = Summarize(outcome.result, structure.topology(), {.digests = o.digests});
  if (const ResultContext* files = runs.files ? runs.files(i) : nullptr) {
    const std::string prefix = runs.many ? o.output + "_" + files->scalar_name : o.output;
    ASSIGN_OR_RETURN(out.files, WriteResultFiles(prefix, *files, outcome.result));
  }
  out.results_s = Seconds(start);
  Phase(context.trace, "results", start);
  return out;
}

// The structure flags through the options module sessions use too (structure_options.h): the
// same names, defaults and ranges. Parse errors name the flag.
absl::StatusOr<StructureOptions> StructureFromFlags(const BenchOptions& o) {
  auto flag = [](const char* name, const absl::Status& status) {
    return absl::Status(status.code(), absl::StrCat("--", name, ": ", status.message()));
  };
  StructureOptions s{.consumers = o.consumers,
                     .producers = o.producers,
                     .buffer_ratio = o.buffer_ratio,
                     .query_readers = 1};
  absl::StatusOr<StructureKind> structure = ParseStructure(o.structure);
  if (!structure.ok()) return flag("structure", structure.status());
  s.kind = *structure;
  absl::StatusOr<std::optional<Prefetch>> prefetch = ParsePrefetch(o.prefetch);
  if (!prefetch.ok()) return flag("prefetch", prefetch.status());
  s.prefetch = *prefetch;
  absl::StatusOr<std::optional<Precompute>> precompute = ParsePrecompute(o.precompute);
  if (!precompute.ok()) return flag("precompute", precompute.status());
  s.precompute = *precompute;
  absl::StatusOr<MissPolicy> miss_policy = ParseMissPolicy(o.miss_policy);
  if (!miss_policy.ok()) return flag("miss-policy", miss_policy.status());
  s.miss_policy = *miss_policy;
  absl::StatusOr<std::optional<ProducerPriority>> priority =
      ParseProducerPriority(o.producer_priority);
  if (!priority.ok()) return flag("producer-priority", priority.status());
  s.producer_priority = *priority;
  s = WithDefaults(s);
  if (absl::Status status = ValidateStructureOptions(s); !status.ok()) {
    // "buffer_ratio: 2 is outside [0, 1]" names the option; here it is the flag --buffer-ratio.
    std::string message(status.message());
    const size_t colon = std::min(message.find(':'), message.size());
    std::replace(message.begin(), message.begin() + colon, '_', '-');
    return absl::Status(status.code(), "--" + message);
  }
  return s;
}

// The run's phases, in the order Run takes them; each is a span of the same name in --trace.

// load: the mesh and the scalar fields the algorithm reads (one, or --scalars' list).
struct Loaded {
  Mesh mesh;
  std::vector<PointField> fields;  // in the order run
  double seconds = 0;
};

// The fields --scalar or --scalars name: "all" is every floating-point field but the block
// labels, in the file's order (a series' time order).
absl::StatusOr<std::vector<int>> SelectFields(const BenchOptions& o, const Mesh& mesh,
                                              Algorithm algorithm) {
  std::vector<int> selected;
  if (o.scalars.empty()) {
    if (ComparesFields(algorithm)) {
      return absl::InvalidArgumentError(absl::StrCat(
          "--scalars: ", std::string(AlgorithmName(algorithm)),
          " compares fields; give at least two, e.g. --scalars F1,F2 or --scalars all"));
    }
    if (!o.scalar.empty() || NeedsScalar(algorithm)) {
      ASSIGN_OR_RETURN(int field, SelectScalarField(mesh, o.scalar, o.block_labels));
      selected.push_back(field);
    }
    return selected;
  }
  if (!o.scalar.empty()) {
    return absl::InvalidArgumentError("give --scalar NAME or --scalars LIST, not both");
  }
  if (!NeedsScalar(algorithm)) {
    return absl::InvalidArgumentError(absl::StrCat(
        "--scalars: ", std::string(AlgorithmName(algorithm)), " reads no scalar field"));
  }
  if (o.scalars == "all") {
    for (size_t f = 0; f < mesh.point_fields.size(); ++f) {
      const PointField& field = mesh.point_fields[f];
      if (field.is_integer || field.name == o.block_labels) continue;
      RETURN_IF_ERROR(ValidateScalarField(field));
      selected.push_back(int(f));
    }
  } else {
    for (const std::string& name : std::vector<std::string>(absl::StrSplit(o.scalars, ','))) {
      if (name.empty()) {
        return absl::InvalidArgumentError(
            absl::StrCat("--scalars: '", o.scalars, "' has an empty field name"));
      }
      absl::StatusOr<int> field = SelectScalarField(mesh, name);
      if (!field.ok()) {
        return absl::Status(field.status().code(),
                            absl::StrCat("--scalars: ", field.status().message()));
      }
      if (std::find(selected.begin(), selected.end(), *field) != selected.end()) {
        return absl::InvalidArgumentError(
            absl::StrCat("--scalars: field '", name, "' is listed twice"));
      }
      selected.push_back(*field);
    }
  }
  if (ComparesFields(algorithm) && selected.size() < 2) {
    return absl::InvalidArgumentError(
        absl::StrCat("--scalars: ", std::string(AlgorithmName(algorithm)),
                     " compares at least two fields; '", o.scalars, "' gives ", selected.size()));
  }
  return selected;
}

absl::StatusOr<Loaded> Load(const BenchOptions& o, Algorithm algorithm,
                            const std::shared_ptr<Trace>& trace) {
  const auto start = Clock::now();
  Loaded out;
  ASSIGN_OR_RETURN(out.mesh, o.mesh.empty() ? io::MakeSample(o.sample)
                                            : io::ReadMesh(o.mesh, {.threads = o.threads}));
  if (o.mesh.empty()) RETURN_IF_ERROR(ValidateMesh(out.mesh));  // ReadMesh validated a file's
  if (!o.block_labels.empty() && out.mesh.FindField(o.block_labels) == nullptr) {
    std::vector<std::string> names;
    for (const PointField& field : out.mesh.point_fields) names.push_back("'" + field.name + "'");
    return absl::NotFoundError(absl::StrCat(
        "--block-labels: point field '", o.block_labels,
        "' not found; point fields: ", names.empty() ? "none" : absl::StrJoin(names, ", ")));
  }
  ASSIGN_OR_RETURN(const std::vector<int> selected, SelectFields(o, out.mesh, algorithm));
  for (int f : selected) out.fields.push_back(out.mesh.point_fields[f]);
  // Without --output no result file carries the mesh's fields: the ones read are copied above,
  // and only the block labels stay, for the partition.
  if (o.output.empty()) {
    std::vector<PointField> kept;
    for (PointField& field : out.mesh.point_fields) {
      if (!o.block_labels.empty() && field.name == o.block_labels) kept.push_back(std::move(field));
    }
    out.mesh.point_fields.swap(kept);
  }
  out.seconds = Seconds(start);
  Phase(trace, "load", start);
  return out;
}

// partition: the blocks and the static encoding.
// `input_corners` gets the order each tetrahedron's vertices came in (TopologyOptions::
// input_corners) when the algorithm needs it (morse-smale, for TTK's triangle order). With no
// --output the mesh's tetrahedra leave memory as the encoding reads them.
absl::StatusOr<std::shared_ptr<const Topology>> Partition(
    const BenchOptions& o, Algorithm algorithm, Mesh& mesh,
    std::shared_ptr<const std::vector<uint8_t>>& input_corners, const std::shared_ptr<Trace>& trace,
    double& seconds) {
  const auto start = Clock::now();
  std::vector<int32_t> blocks;
  {
    Trace::Scope span(trace.get(), "blocks", "encode");
    absl::StatusOr<std::vector<int32_t>> computed =
        ComputeBlocks(mesh, {.bucket_capacity = o.block_size, .block_label_field = o.block_labels});
    if (!computed.ok()) {  // named by the flags typed
      return absl::Status(
          computed.status().code(),
          absl::StrReplaceAll(computed.status().message(), {{"block labels: ", "--block-labels: "},
                                                            {"block size: ", "--block-size: "}}));
    }
    blocks = *std::move(computed);
  }
  // Without --output the points have done their part once the blocks are known: free them
  // before the encoding's peak (24 bytes per vertex).
  if (o.output.empty()) std::vector<double>().swap(mesh.points);
  // Morse-Smale's corners are taken while the tetrahedra are encoded. Without --output the
  // encoding may give the mesh's tetrahedra back page by page as it reads them, and they are
  // freed once read.
  std::vector<uint8_t> corners;
  const bool keep_tetrahedra = !o.output.empty();
  ASSIGN_OR_RETURN(
      std::shared_ptr<const Topology> topology,
      Topology::Build(mesh, blocks,
                      {.threads = o.threads,
                       .tetrahedra_read =
                           [&](const Topology&) {
                             if (!keep_tetrahedra) std::vector<SimplexId>().swap(mesh.tetrahedra);
                           },
                       .input_corners = algorithm == Algorithm::kMorseSmale ? &corners : nullptr,
                       .release_tetrahedra = !keep_tetrahedra,
                       // A tree with a threshold simplifies first, which reads edges.
                       .faces = NeedsFaces(algorithm) || !o.persistence_threshold.empty() ||
                                !o.relative_threshold.empty(),
                       .trace = trace.get()}));
  if (algorithm == Algorithm::kMorseSmale) {
    input_corners = std::make_shared<const std::vector<uint8_t>>(std::move(corners));
  }
  seconds = Seconds(start);
  Phase(trace, "partition", start);
  return topology;
}

// vertex order: the algorithm's input for one field, with the vertex order as its
// preconditioning (like TTK's offsets; counted in `preprocess`) and the parameters given as flags.
absl::StatusOr<AlgorithmInput> PrepareInput(
    const BenchOptions& o, Algorithm algorithm, const Topology& topology,
    std::span<const double> scalars, std::shared_ptr<const std::vector<uint8_t>> input_corners,
    const std::shared_ptr<Trace>& trace, double& seconds) {
  const auto start = Clock::now();
  AlgorithmInput input{
      .algorithm = algorithm,
      .critical_points = {.boundary_rule = o.boundary_rule == "none" ? BoundaryRule::kNone
                                                                     : BoundaryRule::kTtk}};
  if (!scalars.empty()) input.order = VertexOrder(topology, scalars);
  input.input_corners = std::move(input_corners);
  // Thresholds go through the service's parameter parser: one spelling, one set of errors.
  std::map<std::string, std::string> parameters;
  if (!o.persistence_threshold.empty())
    parameters["persistence_threshold"] = o.persistence_threshold;
  if (!o.relative_threshold.empty()) parameters["relative_threshold"] = o.relative_threshold;
  if (!o.embedding.empty()) parameters["embedding"] = o.embedding;
  if (!o.tree.empty()) parameters["tree"] = o.tree;
  if (!o.backend.empty()) parameters["backend"] = o.backend;
  if (!o.relations.empty()) parameters["relations"] = o.relations;
  if (!o.p.empty()) parameters["p"] = o.p;
  if (!o.matching.empty()) parameters["matching"] = o.matching;
  if (o.essential) parameters["essential"] = "true";
  if (absl::Status s = ApplyParameters(parameters, input); !s.ok()) {
    // "parameters.relative_threshold: ..." is the flag --relative-threshold here.
    std::string message(s.message());
    if (absl::StartsWith(message, "parameters.")) {
      const size_t colon = std::min(message.find(':'), message.size());
      std::replace(message.begin(), message.begin() + colon, '_', '-');
      message = "--" + message.substr(std::string_view("parameters.").size());
    }
    return absl::Status(s.code(), message);
  }
  if (NeedsScalarValues(input)) input.scalars.assign(scalars.begin(), scalars.end());
  seconds = Seconds(start);
  Phase(trace, "vertex order", start);
  return input;
}

// Every field's run on one structure: the vertex order, the algorithm, its summary.
template <TopologicalStructure Structure>
absl::StatusOr<std::vector<FieldOutput>> RunFields(Structure& structure, const FieldRuns& runs,
                                                   const RunContext& context,
                                                   const BenchOptions& o) {
  std::vector<FieldOutput> outputs;
  for (size_t i = 0; i < runs.count; ++i) {
    double order_s = 0;
    ASSIGN_OR_RETURN(const AlgorithmInput input, runs.input(i, order_s));
    ASSIGN_OR_RETURN(FieldOutput out, RunAndSummarize(structure, input, context, o, runs, i));
    out.order_s = order_s;
    outputs.push_back(std::move(out));
  }
  return outputs;
}

// preprocess and run, on each kind of structure. The structure is built once for all the
// fields (explicit: its relations; compact: its cache carries over); actopo starts an engine per
// field, as the service does per job, configured for the algorithm.
absl::StatusOr<RunOutput> RunOnExplicit(std::shared_ptr<const Topology> topology,
                                        const RelationSet& declared, const FieldRuns& runs,
                                        const RunContext& context, const BenchOptions& o) {
  const auto start = Clock::now();
  ASSIGN_OR_RETURN(
      auto structure,
      ExplicitStructure::Build(std::move(topology), {.relations = declared, .threads = o.threads}));
  RunOutput out;
  out.preprocess_s = Seconds(start);
  Phase(context.trace, "preprocess", start);
  ASSIGN_OR_RETURN(out.fields, RunFields(*structure, runs, context, o));
  out.memory = structure->memory();
  return out;
}

// The engine's own figures: its configuration, who computed what, and each consumer's wait.
Json EngineDetail(const ActopoStructure& structure, const ActopoStructure::Options& engine) {
  const EngineStats stats = structure.stats();
  Json detail = {{"producers", engine.producers},
                 {"prefetch", std::string(PrefetchName(engine.prefetch))},
                 {"precompute", std::string(PrecomputeName(engine.precompute))},
                 {"miss_policy", std::string(MissPolicyName(engine.miss_policy))},
                 {"producer_priority", std::string(ProducerPriorityName(engine.producer_priority))},
                 {"buffer_capacity_blocks", structure.buffer_capacity_blocks()},
                 {"leader_relations", stats.leader_relations},
                 {"worker_relations", stats.worker_relations},
                 {"consumer_relations", stats.consumer_relations},
                 {"duplicates_avoided", stats.duplicates_avoided},
                 {"waits_abandoned", stats.waits_abandoned},
                 {"blocks_inserted", stats.blocks_inserted},
                 {"producer_busy_s", stats.producer_busy_ns * 1e-9}};
  Json per_consumer = Json::array();
  for (const EngineStats& c : structure.consumer_stats()) {
    per_consumer.push_back({{"wait_s", c.access.wait_ns * 1e-9},
                            {"requests", c.access.requests},
                            {"hits", c.access.hits},
                            {"misses", c.access.misses},
                            {"buffer_peak_bytes", c.buffer_peak_bytes}});
  }
  detail["consumers"] = per_consumer;
  return detail;
}

absl::StatusOr<RunOutput> RunOnActopo(std::shared_ptr<const Topology> topology,
                                      const StructureOptions& options, Algorithm algorithm,
                                      const RelationSet& swept, const FieldRuns& runs,
                                      const RunContext& context, const BenchOptions& o) {
  ActopoStructure::Options engine = EngineOptions(options, algorithm);
  engine.declared = swept;
  RunOutput out;
  for (size_t i = 0; i < runs.count; ++i) {
    const auto start = Clock::now();
    ASSIGN_OR_RETURN(auto structure, ActopoStructure::Create(topology, engine));
    out.preprocess_s += Seconds(start);
    Phase(context.trace, "preprocess", start);
    FieldRuns one = runs;
    one.input = [&](size_t, double& order_s) { return runs.input(i, order_s); };
    one.files = [&](size_t) { return runs.files ? runs.files(i) : nullptr; };
    one.keep = [&](size_t, const AlgorithmOutcome& outcome) {
      if (runs.keep) runs.keep(i, outcome);
    };
    one.count = 1;
    ASSIGN_OR_RETURN(std::vector<FieldOutput> field, RunFields(*structure, one, context, o));
    // Producers still finishing a prefetch would count it after the statistics were read;
    // joined first, the statistics count everything the trace holds.
    structure->Shutdown();
    out.fields.push_back(std::move(field[0]));
    out.access += structure->stats().access;
    const MemoryStats memory = structure->memory();
    out.memory.static_bytes = memory.static_bytes;
    out.memory.relation_peak_bytes =
        std::max(out.memory.relation_peak_bytes, memory.relation_peak_bytes);
    out.engine_detail = EngineDetail(*structure, engine);
  }
  return out;
}

absl::StatusOr<RunOutput> RunOnCompact(std::shared_ptr<const Topology> topology,
                                       const StructureOptions& options, const FieldRuns& runs,
                                       const RunContext& context, const BenchOptions& o) {
  CompactStructure structure(std::move(topology), CacheOptions(options, options.consumers));
  RunOutput out;
  ASSIGN_OR_RETURN(out.fields, RunFields(structure, runs, context, o));
  out.access = structure.stats();
  out.memory = structure.memory();
  return out;
}

// The phases' times (seconds); run, preprocess and results come with the RunOutput.
struct PhaseTimes {
  double load = 0, partition = 0;
};

// The JSON report (README "actopo-bench"). `compared`: diagram-distance's matrices.
Json Report(const BenchOptions& o, Algorithm algorithm, const Topology& topology,
            const PhaseTimes& times, const RunOutput& out, const Json& compared) {
  const TopologyBytes static_bytes = topology.bytes();
  double order_s = 0, run_s = 0, results_s = 0;
  int64_t peak_before_results = 0;
  std::vector<std::string> names;
  for (const FieldOutput& f : out.fields) {
    order_s += f.order_s;
    run_s += f.run_s;
    results_s += f.results_s;
    peak_before_results = std::max(peak_before_results, f.peak_rss_after_run);
    if (!f.field.empty()) names.push_back(f.field);
  }
  const bool many = !o.scalars.empty();
  Json j;
  j["mesh"] = {{"source", o.mesh.empty() ? "sample:" + o.sample : o.mesh},
               {"vertices", topology.num_vertices()},
               // null when the algorithm needs no faces (critical points): none were built.
               {"edges", topology.has_faces() ? Json(topology.num_edges()) : Json(nullptr)},
               {"triangles", topology.has_faces() ? Json(topology.num_triangles()) : Json(nullptr)},
               {"tetrahedra", topology.num_tetrahedra()},
               {"blocks", topology.num_blocks()}};
  j["structure"] = o.structure;
  j["algorithm"] = std::string(AlgorithmName(algorithm));
  j["config"] = {{"consumers", o.consumers},
                 {"producers", o.structure == "actopo" ? Json(o.producers) : Json(nullptr)},
                 {"prefetch", o.structure == "actopo" ? Json(o.prefetch) : Json(nullptr)},
                 {"precompute", o.structure == "actopo" ? Json(o.precompute) : Json(nullptr)},
                 {"buffer_ratio", o.buffer_ratio},
                 {"block_size", o.block_labels.empty() ? Json(o.block_size) : Json(nullptr)},
                 {"block_labels", o.block_labels.empty() ? Json(nullptr) : Json(o.block_labels)},
                 {"scalar", many || names.empty() ? Json(nullptr) : Json(names[0])},
                 {"scalars", many ? Json(names) : Json(nullptr)},
                 {"boundary_rule",
                  algorithm == Algorithm::kCriticalPoints ? Json(o.boundary_rule) : Json(nullptr)},
                 {"preprocess_threads", o.threads > 0 ? o.threads : DefaultThreads()}};
  j["times_s"] = {{"load", times.load},
                  {"partition", times.partition},
                  {"preprocess", order_s + out.preprocess_s},
                  {"run", run_s},
                  {"results", results_s},
                  {"total", Seconds(kProcessStart)}};
  if (compared.contains("distance_seconds")) {
    j["times_s"]["distances"] = compared["distance_seconds"];
  }
  if (compared.contains("tracking_seconds")) {
    j["times_s"]["tracking"] = compared["tracking_seconds"];
  }
  j["engine"] = {{"wait_s", out.access.wait_ns * 1e-9},
                 {"requests", out.access.requests},
                 {"hits", out.access.hits},
                 {"misses", out.access.misses},
                 {"evictions", out.access.evictions},
                 {"blocks_computed", out.access.relations_computed}};
  for (auto& [key, value] : out.engine_detail.items()) j["engine"][key] = value;
  j["memory"] = {
      {"peak_rss_bytes", PeakRssBytes()},  // the whole process, results included
      {"peak_rss_before_results_bytes", peak_before_results},
      {"structure_bytes",
       out.memory.static_bytes + (o.structure == "explicit" ? out.memory.relation_bytes : 0)},
      {"static_bytes", out.memory.static_bytes},
      {"static_breakdown_bytes",
       {{"vertices", static_bytes.vertices},
        {"edges", static_bytes.edges},
        {"triangles", static_bytes.triangles},
        {"tetrahedra", static_bytes.tetrahedra},
        {"blocks", static_bytes.blocks}}},
      {"buffer_peak_bytes", o.structure == "explicit" ? 0 : out.memory.relation_peak_bytes}};
  if (!many) {
    j["result"] = out.fields.at(0).result;
    if (!out.fields[0].files.empty()) j["files"] = out.fields[0].files;
    return j;
  }
  // One entry per field, in the order run; diagram-distance's matrices as the result.
  Json fields = Json::array();
  for (const FieldOutput& f : out.fields) {
    Json entry = {
        {"scalar", f.field},
        {"times_s", {{"preprocess", f.order_s}, {"run", f.run_s}, {"results", f.results_s}}},
        {"result", f.result}};
    if (!f.files.empty()) entry["files"] = f.files;
    fields.push_back(std::move(entry));
  }
  j["fields"] = std::move(fields);
  if (compared.is_object()) j["result"] = compared;
  return j;
}

// The whole run: flags checked, then load, partition, and per field vertex order, preprocess,
// run and results, then the report (and the trace, with --trace).
absl::StatusOr<Json> Run(BenchOptions o) {
  RETURN_IF_ERROR(Validate(o));
  ASSIGN_OR_RETURN(const StructureOptions options, StructureFromFlags(o));
  o.consumers = options.consumers;
  o.producers = options.producers;
  ASSIGN_OR_RETURN(const Algorithm algorithm, ParseAlgorithm(o.algorithm));
  // The trace file is opened first: a path that cannot be written fails before the work.
  std::shared_ptr<Trace> trace;
  std::ofstream trace_file;
  if (!o.trace.empty()) {
    trace_file.open(o.trace);
    if (!trace_file) {
      return absl::InvalidArgumentError(
          absl::StrCat("--trace: cannot write '", o.trace, "': ", std::strerror(errno)));
    }
    trace = std::make_shared<Trace>();
    SetThreadRole("main");
  }

  PhaseTimes times;
  ASSIGN_OR_RETURN(Loaded loaded, Load(o, algorithm, trace));
  times.load = loaded.seconds;
  std::shared_ptr<const std::vector<uint8_t>> input_corners;
  ASSIGN_OR_RETURN(std::shared_ptr<const Topology> topology,
                   Partition(o, algorithm, loaded.mesh, input_corners, trace, times.partition));
  // Without --output the points and other fields are not needed: free them so peak RSS
  // reflects the structures.
  std::vector<ResultContext> files;
  if (o.output.empty()) {
    loaded.mesh = Mesh();
  } else {
    auto boundary = std::make_shared<VertexBoundary>(*topology);
    for (const PointField& f : loaded.fields) {
      files.push_back(ResultContext{loaded.mesh, *topology, f.name, f.values, boundary});
    }
    if (files.empty()) files.push_back(ResultContext{loaded.mesh, *topology, "", {}, boundary});
  }
  // The first field's input (the parameters checked) before any structure is built; the
  // others' as their turn comes.
  const auto values_of = [&](size_t i) {
    return loaded.fields.empty() ? std::span<const double>() : loaded.fields[i].values;
  };
  double first_order_s = 0;
  ASSIGN_OR_RETURN(AlgorithmInput first, PrepareInput(o, algorithm, *topology, values_of(0),
                                                      input_corners, trace, first_order_s));
  const RelationSet declared = DeclaredRelations(first), swept = SweptRelations(first);
  const DistanceParameters distance = first.distance;
  if (absl::Status s = CheckMatchingEntry(distance, loaded.fields.size()); !s.ok()) {
    return absl::Status(s.code(), absl::StrReplaceAll(s.message(), {{"parameters.", "--"}}));
  }
  std::vector<FieldDiagram> diagrams(ComparesFields(algorithm) ? loaded.fields.size() : 0);
  FieldRuns runs{
      .count = std::max<size_t>(1, loaded.fields.size()),
      .input = [&](size_t i, double& order_s) -> absl::StatusOr<AlgorithmInput> {
        if (i == 0) {
          order_s = first_order_s;
          return std::move(first);
        }
        return PrepareInput(o, algorithm, *topology, values_of(i), input_corners, trace, order_s);
      },
      .files = [&](size_t i) { return files.empty() ? nullptr : &files[i]; },
      .keep =
          [&](size_t i, const AlgorithmOutcome& outcome) {
            if (diagrams.empty()) return;
            diagrams[i] = ToFieldDiagram(loaded.fields[i].name,
                                         std::get<PersistenceDiagramResult>(outcome.result),
                                         loaded.fields[i].values, distance);
          },
      .many = !o.scalars.empty()};
  const RunContext context{.consumers = o.consumers, .trace = trace};
  absl::StatusOr<RunOutput> run =
      options.kind == StructureKind::kExplicit ? RunOnExplicit(topology, declared, runs, context, o)
      : options.kind == StructureKind::kActopo
          ? RunOnActopo(topology, options, algorithm, swept, runs, context, o)
          : RunOnCompact(topology, options, runs, context, o);
  RETURN_IF_ERROR(run.status());
  RunOutput& out = *run;
  for (size_t i = 0; i < loaded.fields.size() && i < out.fields.size(); ++i) {
    out.fields[i].field = loaded.fields[i].name;
  }
  Json compared;
  if (algorithm == Algorithm::kDiagramDistance) {
    const auto start = Clock::now();
    compared =
        FieldDistancesJson(CompareFieldDiagrams(diagrams, distance, {.threads = o.consumers}));
    Phase(trace, "distances", start);
  } else if (algorithm == Algorithm::kTracking) {
    const auto start = Clock::now();
    const FieldTracking tracking = TrackFieldDiagrams(diagrams, distance, o.consumers);
    compared = FieldTrackingJson(tracking);
    Phase(trace, "tracking", start);
    if (!o.output.empty()) {
      const std::string path = o.output + "_tracking.vtp";
      RETURN_IF_ERROR(
          io::WritePolyData(path, TrackingPolyData(tracking, diagrams, loaded.mesh.points)));
      compared["files"] = {path};
    }
  }

  Json j = Report(o, algorithm, *topology, times, out, compared);
  if (trace) {
    trace->WriteJson(trace_file);
    trace_file.close();
    if (!trace_file) {
      return absl::InternalError(absl::StrCat("--trace: writing '", o.trace, "' failed"));
    }
    j["trace"] = {{"file", o.trace}, {"events", trace->events()}, {"dropped", trace->dropped()}};
  }
  return j;
}

void PrintHuman(const Json& j) {
  const Json& m = j["mesh"];
  const std::string faces = m["edges"].is_null()
                                ? std::string("edges and triangles not built")
                                : absl::StrCat(m["edges"].get<long long>(), " edges, ",
                                               m["triangles"].get<long long>(), " triangles");
  std::printf("mesh       %s: %lld vertices, %s, %lld tetrahedra, %lld blocks\n",
              m["source"].get<std::string>().c_str(), m["vertices"].get<long long>(), faces.c_str(),
              m["tetrahedra"].get<long long>(), m["blocks"].get<long long>());
  std::printf("run        %s on %s, %d consumer(s)\n", j["algorithm"].get<std::string>().c_str(),
              j["structure"].get<std::string>().c_str(), j["config"]["consumers"].get<int>());
  const Json& t = j["times_s"];
  std::printf(
      "times (s)  load %.3f  partition %.3f  preprocess %.3f  run %.3f  results %.3f  total %.3f\n",
      t["load"].get<double>(), t["partition"].get<double>(), t["preprocess"].get<double>(),
      t["run"].get<double>(), t["results"].get<double>(), t["total"].get<double>());
  const Json& e = j["engine"];
  std::printf("access     requests %lld  hits %lld  misses %lld  evictions %lld  wait %.3f s\n",
              e["requests"].get<long long>(), e["hits"].get<long long>(),
              e["misses"].get<long long>(), e["evictions"].get<long long>(),
              e["wait_s"].get<double>());
  const Json& mem = j["memory"];
  std::printf("memory     peak RSS %.1f MiB  structure %.1f MiB  buffer peak %.1f MiB\n",
              mem["peak_rss_bytes"].get<double>() / 1048576.0,
              mem["structure_bytes"].get<double>() / 1048576.0,
              mem["buffer_peak_bytes"].get<double>() / 1048576.0);
  std::printf("result     %s\n", j["result"].dump().c_str());
  if (j.contains("files")) {
    for (const auto& f : j["files"]) std::printf("wrote      %s\n", f.get<std::string>().c_str());
  }
  if (j.contains("trace")) {
    std::printf("trace      %s (%lld events, %lld dropped)\n",
                j["trace"]["file"].get<std::string>().c_str(),
                j["trace"]["events"].get<long long>(), j["trace"]["dropped"].get<long long>());
  }
}

}  // namespace
}  // namespace actopo

int main(int argc, char** argv) {
  actopo::ConfigureAllocator(actopo::DefaultThreads());
  actopo::BenchOptions o;
  actopo::FlagParser flags("actopo-bench",
                           "runs one algorithm in-process on a mesh and reports times, memory, "
                           "access statistics and the result");
  flags.Add("mesh", &o.mesh, "mesh file (.vtu, legacy .vtk unstructured grid, .vti)");
  flags.Add("sample", &o.sample,
            "built-in sample instead of a file: " + absl::StrJoin(actopo::io::SampleNames(), "; "));
  flags.Add("scalar", &o.scalar, "point scalar field (default: first floating-point field)");
  flags.Add("scalars", &o.scalars,
            "many fields in one process: F1,F2,... or all (every floating-point field, in the "
            "file's order); the structure is built once and the JSON has one entry per field");
  flags.Add("algorithm", &o.algorithm,
            "topo-relations, critical-points, discrete-gradient, morse-smale, persistence-diagram, "
            "topological-simplification, diagram-distance (over --scalars: the fields' "
            "persistence diagrams and the Wasserstein and bottleneck distances of every two) or "
            "tracking (over --scalars in time order: the pairs of consecutive fields matched "
            "and chained into trajectories; --output writes PREFIX_tracking.vtp)");
  flags.Add("p", &o.p, "diagram-distance, tracking: the Wasserstein order (default 2)");
  flags.Add("matching", &o.matching,
            "diagram-distance: I,J (positions in --scalars, from 0): also report the optimal "
            "matching behind that entry, pairs by their PairIdentifier in each field's diagram");
  flags.Add("essential", &o.essential,
            "diagram-distance, tracking: match the infinite pairs too (by birth); distances are "
            "infinite where their counts differ");
  flags.Add("boundary-rule", &o.boundary_rule,
            "critical-points: ttk (TTK >= 1.1 boundary saddles) or none");
  flags.Add("persistence-threshold", &o.persistence_threshold,
            "topological-simplification, morse-smale, merge-tree, contour-tree: keep the "
            "persistence pairs at least this "
            "persistent (absolute) and simplify the rest away first; diagram-distance, tracking: "
            "compare only those pairs");
  flags.Add("relative-threshold", &o.relative_threshold,
            "as --persistence-threshold, as a fraction of the field's range (e.g. 0.01)");
  flags.Add("backend", &o.backend,
            "topological-simplification, morse-smale with a threshold: lts (TTK's default) or "
            "legacy");
  flags.Add("tree", &o.tree, "merge-tree: join (the default) or split");
  flags.Add("embedding", &o.embedding,
            "persistence-diagram --output: diagram (TTK's birth-death plane) or domain");
  flags.Add("relations", &o.relations,
            "topo-relations: ttk (TTK's 20 relations, the default) or all (22: adds the edge "
            "and triangle neighbours)");
  flags.Add("structure", &o.structure, "explicit, compact or actopo");
  flags.Add("consumers", &o.consumers,
            "consumer threads running the algorithm (0: from the cores, see DefaultThreadPlan)");
  flags.Add("producers", &o.producers,
            "actopo: producers per consumer, 1 leader + workers (0: from the cores)");
  flags.Add("buffer-ratio", &o.buffer_ratio,
            "compact cache / actopo buffer capacity as a fraction of the blocks, over all "
            "consumers");
  flags.Add("prefetch", &o.prefetch, "actopo: auto (per algorithm), linear, spatial or adaptive");
  flags.Add("precompute", &o.precompute, "actopo: auto (per algorithm), requested or declared");
  flags.Add("miss-policy", &o.miss_policy,
            "actopo: who computes a missed relation: leader (the paper) or consumer");
  flags.Add("producer-priority", &o.producer_priority,
            "actopo: auto (idle when the consumers take every core), normal or idle (SCHED_IDLE: "
            "producers run only on cycles the consumers leave)");
  flags.Add("block-size", &o.block_size, "octree bucket capacity: max vertices per block");
  flags.Add("block-labels", &o.block_labels,
            "partition by this integer point field instead of the octree");
  flags.Add("threads", &o.threads, "preprocessing threads (0: all cores)");
  flags.Add("output", &o.output,
            "write the result for ParaView as PREFIX_*.vtp / PREFIX_segmentation.vtu");
  flags.Add("trace", &o.trace,
            "write a Chrome trace-event JSON of the run to this file (open it in Perfetto or "
            "chrome://tracing): phases, and per thread every block relation computed, every "
            "consumer wait and every eviction");
  flags.Add("json", &o.json, "print one JSON object");
  flags.Add("digests", &o.digests,
            "add the result's SHA-256 digests (*_sha256, comparable with TTK's); they cost time "
            "on large meshes, so they are off unless asked");
  if (absl::Status s = flags.Parse(argc, argv); !s.ok()) {
    std::cerr << "actopo-bench: " << s.message() << "\n";
    return 2;
  }
  if (flags.help_requested()) {
    std::cout << flags.Usage();
    return 0;
  }
  // A sample is written sample:NAME everywhere; so it may be here, as the mesh or the sample.
  if (o.mesh.starts_with("sample:")) std::swap(o.mesh, o.sample);
  if (o.sample.starts_with("sample:")) o.sample.erase(0, 7);
  // --output's folder is made before the work, as the CLI does.
  if (const std::filesystem::path folder = std::filesystem::path(o.output).parent_path();
      !o.output.empty() && !folder.empty()) {
    std::error_code error;
    std::filesystem::create_directories(folder, error);
    if (error) {
      std::cerr << "actopo-bench: --output: cannot make the folder '" << folder.string()
                << "': " << error.message() << "\n";
      return 1;
    }
  }
  const absl::StatusOr<actopo::Json> result = actopo::Run(o);
  if (!result.ok()) {
    std::cerr << "actopo-bench: " << result.status().message() << "\n";
    return 1;
  }
  if (o.json) {
    std::cout << result->dump(1) << "\n";
  } else {
    actopo::PrintHuman(*result);
  }
  return 0;
}
