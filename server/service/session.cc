#include "server/service/session.h"

#include <algorithm>
#include <chrono>
#include <numeric>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "server/algorithms/discrete_gradient.h"
#include "server/algorithms/vertex_order.h"
#include "server/core/status_macros.h"
#include "server/service/ids.h"

namespace actopo::service {
namespace {

using Clock = std::chrono::steady_clock;

int64_t NanosSince(Clock::time_point start) {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(Clock::now() - start).count();
}

constexpr std::string_view kDimensionNames[4] = {"vertex", "edge", "triangle", "tetrahedron"};
// "a vertex", "an edge", ...
std::string WithArticle(int dimension) {
  return absl::StrCat(dimension == 1 ? "an " : "a ", std::string(kDimensionNames[dimension]));
}

// Bytes per tetrahedron of the relations an explicit structure stores by default (all but the
// edge and triangle neighbours), as actopo-bench's structure_bytes - static_bytes gives them on
// jittered:96. With those two it would be 540.
constexpr int64_t kAllRelationsBytesPerTet = 380;

}  // namespace

std::string FieldRef::ToString() const {
  return index < 0 ? std::string(name) : absl::StrCat(std::string(name), "[", index, "]");
}

int64_t Session::EstimateBytes(const LoadedMesh& mesh, const SessionOptions& options) {
  const StructureOptions& o = options.structure;
  const int64_t tets = mesh.topology->num_tetrahedra();
  const int64_t blocks = mesh.topology->num_blocks();
  // The vertex order (the mesh holds Morse-Smale's InputCorners for all its sessions).
  const int64_t order = int64_t(mesh.topology->num_vertices()) * 4;
  if (o.kind == StructureKind::kExplicit) return order + tets * kAllRelationsBytesPerTet;
  // Buffers hold about buffer_ratio of all relations, plus one state cell per (block,
  // relation) per consumer (16 bytes each).
  const int64_t cells = blocks * kNumRelations * 16 * (o.consumers + 1);
  return order + int64_t(o.buffer_ratio * tets * kAllRelationsBytesPerTet) + cells;
}

int Session::QueryThreads(const SessionOptions& options) {
  const StructureOptions& o = options.structure;
  return o.kind == StructureKind::kActopo ? o.query_readers * o.producers : 0;
}

int Session::JobThreads(const SessionOptions& options) {
  const StructureOptions& o = options.structure;
  const int producers = o.kind == StructureKind::kActopo ? o.producers : 0;
  return o.consumers * (1 + producers);
}

absl::Status Session::Validate(const SessionOptions& options) {
  return ValidateStructureOptions(options.structure, "engine.");
}

absl::StatusOr<std::unique_ptr<Session>> Session::Open(std::shared_ptr<const LoadedMesh> mesh,
                                                       const SessionOptions& options,
                                                       MemoryBudget* budget,
                                                       const Progress& progress) {
  RETURN_IF_ERROR(Validate(options));
  auto s = std::unique_ptr<Session>(new Session());
  ASSIGN_OR_RETURN(s->scalar_, mesh->fields.Select(options.scalar_field));
  s->scalar_name_ = s->scalar_->field.name;
  const int64_t estimate = EstimateBytes(*mesh, options);
  RETURN_IF_ERROR(budget->Reserve(
      estimate, absl::StrCat("a ", std::string(StructureName(options.structure.kind)),
                             " session on mesh '", mesh->id, "'")));
  s->reservation_ = Reservation(budget, estimate);
  s->id_ = NewId("session");
  s->mesh_ = mesh;
  s->options_ = options;
  s->created_ = absl::Now();
  s->Touch();

  // Explicit stores every relation of the mesh, TTK's 20, most of them about edges or triangles.
  // Built once for the mesh, so not the session's preprocessing: sessions compare on their own.
  if (options.structure.kind == StructureKind::kExplicit)
    RETURN_IF_ERROR(mesh->EnsureFaces(progress));
  const auto start = Clock::now();
  RETURN_IF_ERROR(progress.Update("precompute", 0));
  s->base_.order = VertexOrder(*mesh->topology, s->scalar_->field.values);
  s->base_.input_corners = mesh->input_corners;
  s->base_.scalars = s->scalar_->field.values;
  const StructureOptions& structure = options.structure;
  switch (structure.kind) {
    case StructureKind::kExplicit: {
      ASSIGN_OR_RETURN(s->explicit_, ExplicitStructure::Build(mesh->topology, {}, progress));
      break;
    }
    case StructureKind::kCompact:
      s->compact_ = std::make_unique<CompactStructure>(
          mesh->topology, CacheOptions(structure, structure.consumers));
      s->query_compact_ = std::make_unique<CompactStructure>(
          mesh->topology, CacheOptions(structure, structure.query_readers));
      s->compact_readers_ = std::make_unique<ReaderPool<CompactStructure::Reader>>(
          structure.query_readers, [q = s->query_compact_.get()] { return q->NewReader(); });
      break;
    case StructureKind::kActopo: {
      ASSIGN_OR_RETURN(s->query_engine_,
                       ActopoStructure::Create(mesh->topology, QueryEngineOptions(structure)));
      s->actopo_readers_ = std::make_unique<ReaderPool<ActopoStructure::Reader>>(
          structure.query_readers, [q = s->query_engine_.get()] { return q->NewReader(); });
      break;
    }
  }
  s->preprocess_seconds_ = std::chrono::duration<double>(Clock::now() - start).count();
  RETURN_IF_ERROR(progress.Update("precompute", 1));
  return s;
}

Session::~Session() = default;  // reader pools before the structures they read (member order)

absl::Time Session::last_used() const {
  return absl::FromUnixNanos(last_used_ns_.load(std::memory_order_relaxed));
}

void Session::Touch() {
  last_used_ns_.store(absl::GetCurrentTimeNanos(), std::memory_order_relaxed);
}

absl::StatusOr<SimplexId> Session::ResolveId(int dimension, int64_t id, FieldRef field) const {
  const Topology& topo = *mesh_->topology;
  const int64_t n = topo.num_simplices(dimension);
  if (id < 0 || id >= n) {
    return absl::OutOfRangeError(absl::StrCat(field.ToString(), ": ",
                                              std::string(kDimensionNames[dimension]), " id ", id,
                                              " is outside [0, ", n, ")"));
  }
  if (dimension == 0) return topo.vertex_internal_id(SimplexId(id));
  if (dimension == 3) return topo.tetrahedron_internal_id(SimplexId(id));
  return SimplexId(id);
}

absl::StatusOr<SimplexId> Session::ResolveVertices(int dimension, std::span<const int64_t> vertices,
                                                   FieldRef field) const {
  const Topology& topo = *mesh_->topology;
  if (int(vertices.size()) != dimension + 1) {
    return absl::InvalidArgumentError(absl::StrCat(field.ToString(), ": ", WithArticle(dimension),
                                                   " has ", dimension + 1, " vertices, got ",
                                                   vertices.size()));
  }
  std::array<SimplexId, 4> v{};
  for (int i = 0; i <= dimension; ++i) {
    if (vertices[i] < 0 || vertices[i] >= topo.num_vertices()) {
      return absl::OutOfRangeError(absl::StrCat(field.ToString(), ": vertex id ", vertices[i],
                                                " is outside [0, ", topo.num_vertices(), ")"));
    }
    v[i] = topo.vertex_internal_id(SimplexId(vertices[i]));
  }
  SortVertexIds(v.data(), dimension + 1);
  SimplexId found = -1;
  switch (dimension) {
    case 0: found = v[0]; break;
    case 1: found = v[0] == v[1] ? -1 : topo.FindEdge(v[0], v[1]); break;
    case 2: found = topo.FindTriangle(v[0], v[1], v[2]); break;
    default: found = topo.FindTetrahedron(v[0], v[1], v[2], v[3]); break;
  }
  if (found < 0) {
    return absl::NotFoundError(absl::StrCat(field.ToString(), ": (", absl::StrJoin(vertices, ", "),
                                            ") is not ", WithArticle(dimension), " of mesh '",
                                            mesh_->id, "'"));
  }
  return found;
}

// The core orders rows by internal ids; on the wire they follow the same rules in the ids the
// client sees: ascending ids, faces in the lexicographic order of their input vertices (the
// (v0v1), (v0v2), ... local orders), links in the order of their star (ascending input ids).
template <class Reader>
void Session::AppendRows(Reader& reader, Relation r, std::span<const SimplexId> simplices,
                         std::vector<int64_t>& offsets, std::vector<int64_t>& values,
                         std::vector<int64_t>* vertices) const {
  const Topology& topo = *mesh_->topology;
  const int target = TargetDimension(r);
  const bool link = r == Relation::kVL || r == Relation::kEL || r == Relation::kFL;
  const Relation star_of_link = r == Relation::kVL   ? Relation::kVT
                                : r == Relation::kEL ? Relation::kET
                                                     : Relation::kFT;
  const bool by_vertices = r == Relation::kFE || r == Relation::kTE || r == Relation::kTF;
  // Rows are reported in canonical order (SEMANTICS.md): by the result's own id for most
  // relations, by the input id of the star tetrahedron at the same position for links, by
  // vertex tuple for the faces of triangles and tetrahedra. Keys within a row are distinct, so
  // an unstable sort gives the one order.
  const bool by_own_id = target >= 0 && !link && !by_vertices;
  struct Item {
    std::array<int64_t, 4> key;
    int64_t id;
    SimplexId internal;
  };
  std::vector<Item> items;  // reused across the batch (links and tuple-ordered faces)
  for (const SimplexId s : simplices) {
    const auto row = reader.get(r, s);
    const size_t begin = values.size();
    if (target < 0) {  // a predicate: one value
      values.insert(values.end(), row.begin(), row.end());
    } else if (by_own_id) {
      // The common case, kept to plain integers: map to reported ids and sort them in place.
      values.resize(begin + row.size());
      int64_t* out = values.data() + begin;
      for (size_t i = 0; i < row.size(); ++i) {
        const SimplexId x = row[i];
        out[i] = target == 0   ? topo.vertex_input_id(x)
                 : target == 3 ? topo.tetrahedron_input_id(x)
                               : x;
      }
      std::sort(out, out + row.size());
      if (vertices != nullptr && (target == 1 || target == 2)) {
        for (size_t i = 0; i < row.size(); ++i) {  // edge and triangle ids are internal
          SimplexId v[4];
          CellTokens(topo, target, SimplexId(out[i]), v);
          vertices->insert(vertices->end(), v, v + target + 1);
        }
      }
    } else {
      items.clear();
      const std::span<const SimplexId> star =
          link ? reader.get(star_of_link, s) : std::span<const SimplexId>();
      for (size_t i = 0; i < row.size(); ++i) {
        const SimplexId x = row[i];
        Item item{{-1, -1, -1, -1}, x, x};
        if (target == 0) item.id = topo.vertex_input_id(x);
        if (target == 3) item.id = topo.tetrahedron_input_id(x);
        if (link) {
          item.key[0] = topo.tetrahedron_input_id(star[i]);
        } else {
          SimplexId v[4];
          CellTokens(topo, target, x, v);
          std::copy(v, v + target + 1, item.key.begin());
        }
        items.push_back(item);
      }
      std::sort(items.begin(), items.end(),
                [](const Item& a, const Item& b) { return a.key < b.key; });
      for (const Item& item : items) {
        values.push_back(item.id);
        if (vertices != nullptr && (target == 1 || target == 2)) {
          SimplexId v[4];
          CellTokens(topo, target, item.internal, v);
          vertices->insert(vertices->end(), v, v + target + 1);
        }
      }
    }
    offsets.push_back(int64_t(values.size()));
  }
}

template <class Reader>
void Session::AppendRowsInBlockOrder(Reader& reader, Relation r,
                                     std::span<const SimplexId> simplices,
                                     std::vector<int64_t>& offsets, std::vector<int64_t>& values,
                                     std::vector<int64_t>* vertices) const {
  if (vertices != nullptr || std::is_sorted(simplices.begin(), simplices.end())) {
    AppendRows(reader, r, simplices, offsets, values, vertices);
    return;
  }
  const size_t n = simplices.size();
  std::vector<uint32_t> order(n);
  std::iota(order.begin(), order.end(), 0u);
  std::sort(order.begin(), order.end(),
            [&](uint32_t a, uint32_t b) { return simplices[a] < simplices[b]; });
  std::vector<SimplexId> sorted(n);
  for (size_t k = 0; k < n; ++k) sorted[k] = simplices[order[k]];
  std::vector<int64_t> sorted_offsets = {0}, sorted_values;
  sorted_offsets.reserve(n + 1);
  AppendRows(reader, r, sorted, sorted_offsets, sorted_values, nullptr);
  std::vector<uint32_t> position(n);  // input item -> its row among the sorted ones
  for (size_t k = 0; k < n; ++k) position[order[k]] = uint32_t(k);
  values.reserve(values.size() + sorted_values.size());
  for (size_t i = 0; i < n; ++i) {
    const size_t k = position[i];
    values.insert(values.end(), sorted_values.begin() + sorted_offsets[k],
                  sorted_values.begin() + sorted_offsets[k + 1]);
    offsets.push_back(int64_t(values.size()));
  }
}

void Session::Query(Relation r, std::span<const SimplexId> simplices, std::vector<int64_t>& offsets,
                    std::vector<int64_t>& values, std::vector<int64_t>* vertices) {
  const auto arrived = Clock::now();
  Touch();
  auto compute_since = arrived;
  if (explicit_) {
    auto reader = explicit_->NewReader();  // read-only: no lock, no pool
    AppendRows(reader, r, simplices, offsets, values, vertices);
  } else if (compact_readers_) {
    auto reader = compact_readers_->Acquire();
    compute_since = Clock::now();
    const AccessStats before = reader->stats();
    AppendRowsInBlockOrder(*reader, r, simplices, offsets, values, vertices);
    // Pooled readers live as long as the session: count their accesses per call.
    MutexLock lock(stats_mu_);
    compact_queries_ += reader->stats().Since(before);
  } else {
    auto reader = actopo_readers_->Acquire();
    compute_since = Clock::now();
    AppendRowsInBlockOrder(*reader, r, simplices, offsets, values, vertices);
  }
  const auto done = Clock::now();
  const auto ns = [](auto d) {
    return std::chrono::duration_cast<std::chrono::nanoseconds>(d).count();
  };
  queries_.fetch_add(1, std::memory_order_relaxed);
  query_ns_.fetch_add(ns(done - arrived), std::memory_order_relaxed);
  query_simplices_.fetch_add(int64_t(simplices.size()), std::memory_order_relaxed);
  query_queue_ns_.fetch_add(ns(compute_since - arrived), std::memory_order_relaxed);
  query_compute_ns_.fetch_add(ns(done - compute_since), std::memory_order_relaxed);
}

void Session::Query(Relation r, SimplexId s, std::vector<int64_t>& ids,
                    std::vector<int64_t>* vertices) {
  std::vector<int64_t> offsets;
  Query(r, std::span<const SimplexId>(&s, 1), offsets, ids, vertices);
}

const ResultContext& Session::result_context() {
  MutexLock lock(result_mu_);
  if (!result_context_) {
    result_context_.emplace(ResultContext{mesh_->mesh, *mesh_->topology, scalar_name_,
                                          scalar_->field.values, mesh_->vertex_boundary});
  }
  return *result_context_;
}

absl::StatusOr<JobOutcome> Session::RunJob(const AlgorithmInput& input, const RunContext& context,
                                           const Progress::Report& prepare, bool whole_job) {
  Touch();
  const auto start = Clock::now();
  RunContext ctx = context;
  ctx.consumers = options_.structure.consumers;
  JobOutcome out;
  if (NeedsFaces(input) && !mesh_->topology->has_faces()) {
    // The first job on the mesh that reads edges or triangles builds them, for every session.
    const auto faces_start = Clock::now();
    const Progress faces({.cancel = ctx.cancel, .deadline = ctx.deadline, .report = prepare});
    RETURN_IF_ERROR(mesh_->EnsureFaces(faces, ctx.trace.get()));
    out.faces_s = std::chrono::duration<double>(Clock::now() - faces_start).count();
  }
  if (explicit_) {
    ASSIGN_OR_RETURN(out.outcome, RunAlgorithm(*explicit_, input, ctx));
    out.memory = explicit_->memory();
  } else if (compact_) {
    // Jobs use readers of their own; the structure totals what finished readers counted.
    const AccessStats before = compact_->stats();
    ASSIGN_OR_RETURN(out.outcome, RunAlgorithm(*compact_, input, ctx));
    out.engine.access = compact_->stats().Since(before);
    out.engine.consumer_relations = out.engine.access.relations_computed;
    out.memory = compact_->memory();
  } else {
    const auto engine_start = Clock::now();
    ActopoStructure::Options engine_options = EngineOptions(options_.structure, input.algorithm);
    engine_options.declared = SweptRelations(input);
    ASSIGN_OR_RETURN(auto engine, ActopoStructure::Create(mesh_->topology, engine_options));
    if (ctx.trace) ctx.trace->Span("start engine", "phase", engine_start, Clock::now());
    absl::StatusOr<AlgorithmOutcome> outcome = RunAlgorithm(*engine, input, ctx);
    // Its producers joined first: a prefetch finishing later would be missing from the
    // statistics while its span is in the job's trace.
    engine->Shutdown();
    out.engine = engine->stats();
    out.memory = engine->memory();
    engine.reset();
    if (!outcome.ok()) return outcome.status();
    out.outcome = std::move(*outcome);
  }
  {
    MutexLock lock(stats_mu_);
    finished_jobs_ += out.engine;
    relation_peak_bytes_ = std::max(relation_peak_bytes_, out.memory.relation_peak_bytes);
  }
  if (whole_job) CountJob(NanosSince(start));
  Touch();
  return out;
}

void Session::CountJob(int64_t ns) {
  jobs_.fetch_add(1, std::memory_order_relaxed);
  job_ns_.fetch_add(ns, std::memory_order_relaxed);
}

SessionStats Session::stats() const {
  SessionStats s;
  {
    MutexLock lock(stats_mu_);
    s.engine = finished_jobs_;
    s.engine.access += compact_queries_;
    s.memory.relation_peak_bytes = relation_peak_bytes_;
  }
  if (query_engine_) s.engine += query_engine_->stats();
  MemoryStats now = explicit_  ? explicit_->memory()
                    : compact_ ? compact_->memory()
                               : query_engine_->memory();
  if (query_compact_) {
    const MemoryStats q = query_compact_->memory();
    now.relation_bytes += q.relation_bytes;
    now.relation_peak_bytes += q.relation_peak_bytes;
  }
  s.memory.static_bytes = now.static_bytes;
  s.memory.relation_bytes = now.relation_bytes;
  s.memory.relation_peak_bytes = std::max(s.memory.relation_peak_bytes, now.relation_peak_bytes);
  s.queries = queries_.load();
  s.query_ns = query_ns_.load();
  s.query_simplices = query_simplices_.load();
  s.query_queue_ns = query_queue_ns_.load();
  s.query_compute_ns = query_compute_ns_.load();
  s.query_serialize_ns = query_serialize_ns_.load();
  s.jobs = jobs_.load();
  s.job_ns = job_ns_.load();
  s.preprocess_seconds = preprocess_seconds_;
  return s;
}

}  // namespace actopo::service
