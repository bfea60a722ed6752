// actopo/client.h: the C++ client of the ACTOPO topology service (proto package actopo.v1).
//
// A `Client` talks to an actopo-server over gRPC. It loads, uploads or downloads tetrahedral
// meshes and adds point fields to them, opens sessions (a topological data structure on a mesh and
// a scalar field), asks relation queries (one simplex, a batch, or a stream) and runs
// TTK-compatible algorithm jobs, on the session's field or over several fields, whose results come
// as named arrays (a persistence diagram's also as pairs: JobResult::PersistencePairs; a merge or
// contour tree's as nodes and arcs: JobResult::Tree) and, comparing fields, as distance matrices
// (JobResult::Distances) or tracked pairs (JobResult::Tracking). Every fallible call returns
// absl::Status or absl::StatusOr<T> carrying the server's gRPC code and message unchanged
// (NOT_FOUND for an unknown mesh, OUT_OF_RANGE for a simplex id past the end, ...); problems the
// client finds itself (an unknown relation name, a ragged array) are INVALID_ARGUMENT before
// anything is sent.
//
// Everything here is in namespace actopo::client; the server's own types (its EngineStats,
// PartitionOptions, ...) are in actopo, so one program may link the client and the server's
// libraries. Ratios of counters (EngineStats::hit_rate) are 1.0 when the denominator is 0.
//
// This is the only public header. The generated protobuf and gRPC types stay inside the
// library, so a program using it depends on Abseil's status types and the standard library
// only.
//
// Example:
//
//   absl::StatusOr<std::unique_ptr<actopo::client::Client>> client =
//       actopo::client::Client::Connect("127.0.0.1:50051");
//   if (!client.ok()) return client.status();
//   absl::StatusOr<actopo::client::MeshInfo> mesh = (*client)->LoadMesh("sample:jittered:20");
//   if (!mesh.ok()) return mesh.status();
//   absl::StatusOr<actopo::client::SessionInfo> session =
//       (*client)->OpenSession(mesh->mesh_id, {.structure = actopo::client::Structure::kCompact});
//   if (!session.ok()) return session.status();
//   absl::StatusOr<std::vector<int64_t>> star =
//       (*client)->Relation(session->session_id, "vertex_star", 7);  // tetrahedra around 7
//   absl::StatusOr<actopo::client::JobResult> result =
//       (*client)->RunJob(session->session_id, "critical-points");
//   if (result.ok()) std::cout << result->summary_json << "\n";  // {"counts": {...}, ...}
//
// Ids: vertices and tetrahedra are named by their input ids (as loaded or uploaded); edges and
// triangles by the service's ids (stable for the life of a mesh) or by their vertex tuples.
//
// Thread safety: a Client may be used from many threads at once. A RelationStream has one
// writer and one reader (which may be two different threads).
#ifndef ACTOPO_CLIENT_H_
#define ACTOPO_CLIENT_H_

#include <chrono>
#include <cstdint>
#include <cstring>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <variant>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"

namespace actopo::client {

namespace internal {
struct Core;  // the channel, the stub and the options, shared by a Client and its streams
}  // namespace internal

// ---------------------------------------------------------------------------------------------
// Arrays: raw little-endian values with an element type and a row-major shape.

// Element type of an Array (the proto's DataType).
enum class DataType { kUnspecified, kFloat32, kFloat64, kInt8, kInt32, kInt64, kUint8 };

// "float32", "float64", "int8", "int32", "int64", "uint8" or "unspecified".
std::string_view DataTypeName(DataType dtype);
// Bytes per element (0 for kUnspecified).
size_t DataTypeSize(DataType dtype);

// The DataType of a C++ element type, kUnspecified for types the wire does not carry.
template <class T>
inline constexpr DataType kDataTypeOf = DataType::kUnspecified;
template <>
inline constexpr DataType kDataTypeOf<float> = DataType::kFloat32;
template <>
inline constexpr DataType kDataTypeOf<double> = DataType::kFloat64;
template <>
inline constexpr DataType kDataTypeOf<int8_t> = DataType::kInt8;
template <>
inline constexpr DataType kDataTypeOf<int32_t> = DataType::kInt32;
template <>
inline constexpr DataType kDataTypeOf<int64_t> = DataType::kInt64;
template <>
inline constexpr DataType kDataTypeOf<uint8_t> = DataType::kUint8;

// A named array, e.g. a result array "critical_points/CriticalType" (int8, shape {n}).
//
//   absl::StatusOr<std::vector<int8_t>> types = array.As<int8_t>();
//   std::vector<double> any = array.ToDouble();   // whatever the dtype
struct Array {
  std::string name;
  DataType dtype = DataType::kUnspecified;
  std::vector<int64_t> shape;  // row-major; the product is the number of elements
  std::string data;            // raw little-endian bytes

  // Number of elements: the product of the shape.
  int64_t size() const;
  // The values as T; INVALID_ARGUMENT unless dtype is kDataTypeOf<T> and the bytes match the
  // shape.
  template <class T>
  absl::StatusOr<std::vector<T>> As() const;
  // The values converted to double, whatever the dtype (empty if the dtype is unspecified).
  std::vector<double> ToDouble() const;
  // The values of an integer array as int64; INVALID_ARGUMENT for floating-point arrays.
  absl::StatusOr<std::vector<int64_t>> ToInt64() const;

  // OK when the dtype is `want` and data holds exactly size() elements of it.
  absl::Status CheckLayout(DataType want) const;
};

template <class T>
absl::StatusOr<std::vector<T>> Array::As() const {
  static_assert(kDataTypeOf<T> != DataType::kUnspecified, "not an element type of the wire");
  if (absl::Status s = CheckLayout(kDataTypeOf<T>); !s.ok()) return s;
  std::vector<T> values(data.size() / sizeof(T));
  if (!values.empty()) std::memcpy(values.data(), data.data(), data.size());
  return values;
}

// ---------------------------------------------------------------------------------------------
// Server.

// Limits enforced by the server.
struct ServerLimits {
  int32_t max_meshes = 0;
  int32_t max_sessions = 0;
  int32_t max_engine_threads = 0;   // consumers and producers over all sessions
  int64_t memory_budget_bytes = 0;  // meshes and sessions
  int64_t max_message_bytes = 0;    // largest gRPC message accepted
  int32_t max_batch_size = 0;       // most simplices in one RelationBatch request
  int64_t session_idle_timeout_seconds = 0;
  int64_t upload_budget_bytes = 0;     // file uploads held at once, announced sizes summed
  int64_t upload_timeout_seconds = 0;  // an upload nobody writes to this long is dropped
  int32_t max_uploads = 0;             // file uploads held at once
};

// Versions, algorithms, relations, samples and limits of a server.
struct ServerInfo {
  std::string version;
  std::map<std::string, std::string> library_versions;  // e.g. "grpc" -> "1.51.1"
  std::vector<std::string> algorithms;                  // "topo-relations", ..., "contour-tree"
  std::vector<std::string> relations;                   // "vertex_neighbors", "vertex_edges", ...
  std::vector<std::string> samples;                     // built-in samples with their descriptions
  ServerLimits limits;
};

// ---------------------------------------------------------------------------------------------
// Meshes.

// A point field of a mesh.
struct FieldInfo {
  std::string name;
  DataType dtype = DataType::kUnspecified;  // as loaded
  double min = 0;
  double max = 0;
  // The time value of a series member: a .pvd collection's step, a LoadSeries file's, or the one
  // given to AddFields.
  std::optional<double> time;
};

// A mesh loaded on the server.
struct MeshInfo {
  std::string mesh_id;
  std::string name;  // file or sample name
  // "file:PATH", "files:PATH,PATH,..." (LoadSeries), "sample:NAME", "upload" (UploadMesh),
  // "upload:FILE" (UploadFile: the file's name, a .pvd's for a series)
  std::string source;
  int64_t vertices = 0;
  // Unset until the server has built them: it loads a mesh without its edges and triangles and
  // builds them for the first job, relation query or explicit session that reads them (critical
  // points never does), or for GetMesh with count_faces.
  std::optional<int64_t> edges;
  std::optional<int64_t> triangles;
  int64_t tetrahedra = 0;
  int32_t blocks = 0;      // blocks of the partition
  int32_t block_size = 0;  // octree bucket capacity used, 0 when partitioned by labels
  std::vector<FieldInfo> fields;
  int64_t bytes = 0;  // the mesh and its static encodings
  int32_t sessions = 0;
  std::chrono::system_clock::time_point created;
  double load_seconds = 0;
  double partition_seconds = 0;
};

// How the server partitions a mesh into blocks.
struct PartitionOptions {
  int32_t block_size = 0;         // octree bucket capacity (max vertices per block); 0: 1000
  std::string block_label_field;  // partition by this integer point field instead
};

// A point field to upload: one value per vertex.
struct ScalarField {
  std::string name;
  std::span<const double> values;
};

// Options of Client::UploadMesh.
struct UploadOptions {
  std::string name;  // shown in MeshInfo::name; empty: "upload"
  PartitionOptions partition;
  size_t chunk_bytes = size_t{1} << 20;  // bytes per message after the header
};

// A point field to add to a loaded mesh (Client::AddFields): one value per vertex of the mesh,
// float64 or float32 (the server keeps float64 and reports the dtype sent), and optionally the
// time value of a series member (FieldInfo::time).
//
//   std::vector<float> pressure = ...;   // one per vertex
//   client->AddField(mesh_id, {.name = "pressure_07", .values = pressure, .time = 0.7});
struct FieldValues {
  std::string name;
  std::variant<std::span<const double>, std::span<const float>> values;
  std::optional<double> time;
};

// Options of Client::AddFields.
struct AddFieldsOptions {
  size_t chunk_bytes = size_t{1} << 20;  // bytes per message after the header
  // The SHA-256 (64 lowercase hex digits) of all the values' bytes in order, which the server
  // checks what it received against (DATA_LOSS if they differ). Unset: computed here from the
  // values before they are sent; empty: none, the server checks nothing. Give the digest known
  // at the data's source to have the whole way checked.
  std::optional<std::string> sha256;
};

// A point field of a downloaded mesh (MeshArrays).
struct MeshField {
  std::string name;
  // The dtype it was loaded or added with: kFloat32, kFloat64, kInt32 or kInt64; `values` holds
  // it widened to double (exact: the server keeps every field as doubles).
  DataType dtype = DataType::kUnspecified;
  std::vector<double> values;  // one per vertex
  std::optional<double> time;  // a series member's (FieldInfo::time)
};

// A loaded mesh as the server holds it (Client::DownloadMesh), in the upload's terms: it uploads
// again as the same mesh.
//
//   auto mesh = client->DownloadMesh(mesh_id, {"height"});
//   auto copy = client->UploadMesh(mesh->points, mesh->tetrahedra,
//                                  {{"height", mesh->fields[0].values}});
struct MeshArrays {
  std::string name;
  std::vector<double> points;       // x, y, z per vertex, in input order
  std::vector<int64_t> tetrahedra;  // 4 input vertex ids per tetrahedron, in the order given
  std::vector<MeshField> fields;    // the fields asked for, in that order

  int64_t vertices() const { return int64_t(points.size() / 3); }
  // The field `name`, or nullptr.
  const MeshField* Field(std::string_view name) const;
};

// Options of Client::DownloadMesh.
struct DownloadOptions {
  // Every point field of the mesh, in its order (GetMesh's), instead of the ones named.
  bool all_fields = false;
  // Called with the fraction of the bytes received (0 to 1) after each chunk, on
  // DownloadMesh's thread.
  std::function<void(double fraction)> progress;
};

// ---------------------------------------------------------------------------------------------
// Sessions.

// The topological data structure of a session.
enum class Structure {
  kActopo,    // the task-parallel engine: producers compute ahead into a bounded buffer
  kExplicit,  // every relation the algorithm needs computed up front
  kCompact,   // relations computed on demand into a bounded cache
};

// Which blocks the actopo producers compute ahead.
enum class Prefetch { kAuto, kLinear, kSpatial, kAdaptive };
// Which relations the actopo producers compute for a block.
enum class Precompute { kAuto, kRequested, kDeclared };

// "actopo", "explicit", "compact"; "auto", "linear", ...; "auto", "requested", "declared".
std::string_view StructureName(Structure structure);
std::string_view PrefetchName(Prefetch prefetch);
std::string_view PrecomputeName(Precompute precompute);

// Options of Client::OpenSession; 0 and kAuto mean the server's default.
struct SessionOptions {
  std::string scalar;  // the scalar field; empty: the mesh's first floating-point field
  Structure structure = Structure::kActopo;
  int32_t consumers = 0;      // algorithm threads; 0: 1
  int32_t producers = 0;      // actopo producer threads per consumer; 0: 2
  double buffer_ratio = 0.0;  // buffer or cache capacity as a fraction of the blocks; 0: 0.2
  Prefetch prefetch = Prefetch::kAuto;
  Precompute precompute = Precompute::kAuto;
};

// An open session, with its engine options as the server resolved them.
struct SessionInfo {
  std::string session_id;
  std::string mesh_id;
  std::string scalar_field;
  Structure structure = Structure::kActopo;
  int32_t consumers = 0;
  int32_t producers = 0;
  double buffer_ratio = 0.0;
  Prefetch prefetch = Prefetch::kAuto;
  Precompute precompute = Precompute::kAuto;
  std::chrono::system_clock::time_point created;
  std::chrono::system_clock::time_point last_used;
  std::string running_job_id;  // empty when no job runs
};

// A cumulative counter: diff two snapshots for an interval.
struct Counter {
  int64_t count = 0;
  int64_t ns = 0;  // total nanoseconds
};

// Access and engine statistics (see the proto's EngineStats).
struct EngineStats {
  int64_t requests = 0;  // block-level relation requests
  int64_t hits = 0;
  int64_t misses = 0;
  int64_t evictions = 0;
  int64_t wait_ns = 0;  // time consumers waited
  int64_t leader_relations = 0;
  int64_t worker_relations = 0;
  int64_t consumer_relations = 0;
  int64_t duplicates_avoided = 0;
  int64_t producer_busy_ns = 0;
  int64_t buffer_bytes = 0;
  int64_t buffer_peak_bytes = 0;
  // Misses a consumer computed itself after waiting for a producer at idle priority that got
  // no cycles (other threads held every core).
  int64_t waits_abandoned = 0;

  // hits / requests; 1.0 without requests (nothing was missed), as in the Python client.
  double hit_rate() const { return requests > 0 ? double(hits) / double(requests) : 1.0; }
};

// Memory of a session.
struct MemoryStats {
  int64_t static_bytes = 0;    // the mesh's static encodings (shared by its sessions)
  int64_t relation_bytes = 0;  // relations stored or buffered now
  int64_t relation_peak_bytes = 0;
  int64_t process_rss_bytes = 0;  // resident memory of the server process
};

// Statistics of a session over its life.
struct SessionStats {
  EngineStats engine;
  MemoryStats memory;
  Counter relation_queries;
  Counter jobs;
  double preprocess_seconds = 0;
};

// ---------------------------------------------------------------------------------------------
// Relations. Names are the proto's Relation values in lower case: "vertex_neighbors",
// "vertex_edges", "vertex_triangles", "vertex_star", "edge_vertices", "edge_triangles",
// "edge_star", "triangle_vertices", "triangle_edges", "triangle_star", "tetrahedron_vertices",
// "tetrahedron_edges", "tetrahedron_triangles", "tetrahedron_neighbors", "vertex_link",
// "edge_link", "triangle_link", "vertex_on_boundary", "edge_on_boundary",
// "triangle_on_boundary", "edge_neighbors" (edges sharing a vertex), "triangle_neighbors"
// (triangles sharing an edge).

// The simplex a relation query is about: an id, or its input vertex ids in any order.
//
//   client->Relation(session, "vertex_star", 7);                             // vertex 7
//   client->Relation(session, "edge_triangles", Simplex::Vertices({3, 17}));  // edge (3, 17)
class Simplex {
 public:
  // Implicit so that an id can be passed where a Simplex is expected.
  Simplex(int64_t id) : id_(id) {}  // NOLINT(google-explicit-constructor)
  // A simplex by its 1 to 4 input vertex ids.
  static Simplex Vertices(std::vector<int64_t> vertices);

  bool by_vertices() const { return by_vertices_; }
  int64_t id() const { return id_; }
  const std::vector<int64_t>& vertices() const { return vertices_; }

 private:
  Simplex() = default;
  int64_t id_ = 0;
  bool by_vertices_ = false;
  std::vector<int64_t> vertices_;
};

// The answer of Client::RelationWithVertices.
struct RelationResult {
  std::vector<int64_t> ids;
  // For relations whose results are edges or triangles: the input vertices of each result,
  // flattened (2 or 3 per id); empty otherwise.
  std::vector<int64_t> vertices;
};

// A relation of many simplices in compressed sparse rows: the results of simplex i are
// values[offsets[i] .. offsets[i + 1]).
struct RelationCsr {
  std::vector<int64_t> offsets;  // size() + 1 entries, offsets[0] == 0
  std::vector<int64_t> values;

  size_t size() const { return offsets.empty() ? 0 : offsets.size() - 1; }
  std::span<const int64_t> operator[](size_t i) const {
    return std::span<const int64_t>(values).subspan(size_t(offsets[i]),
                                                    size_t(offsets[i + 1] - offsets[i]));
  }
};

// An item of a batch that failed: its position in the request and why.
struct ItemError {
  int64_t index = 0;
  absl::Status status;
};

// One answer of a relation stream: the request's id and its result, or its own error (the
// stream goes on after a bad request).
struct StreamItem {
  int64_t request_id = 0;
  // A single simplex's result (Write), or the request's error (also for a batch that failed as
  // a whole: unknown session, bad array).
  absl::StatusOr<std::vector<int64_t>> ids;
  // A batch's answer (WriteBatch): one row per simplex; a failed item's row is empty and the
  // item is listed in item_errors, the others are answered.
  RelationCsr rows;
  std::vector<ItemError> item_errors;
};

// A bidirectional relation stream (Client::OpenRelationStream). Write requests from one
// thread and Read answers from another (or alternate in one thread: answers come one per
// request, in order); WritesDone when all are sent; Read until it returns nullopt; then Finish.
//
//   auto stream = client->OpenRelationStream();
//   std::thread writer([&] {
//     for (int64_t v = 0; v < n; ++v) (*stream)->Write(v, session, "vertex_neighbors", v);
//     (*stream)->WritesDone();
//   });
//   while (std::optional<StreamItem> item = (*stream)->Read()) { ... }
//   writer.join();
//   absl::Status status = (*stream)->Finish();
class RelationStream {
 public:
  struct Impl;
  explicit RelationStream(std::unique_ptr<Impl> impl);
  RelationStream(const RelationStream&) = delete;
  RelationStream& operator=(const RelationStream&) = delete;
  // Cancels the call if it was not finished.
  ~RelationStream();

  // Sends one request. INVALID_ARGUMENT for an unknown relation name (nothing is sent);
  // FAILED_PRECONDITION once the stream is broken or WritesDone was called (Finish says why).
  absl::Status Write(int64_t request_id, std::string_view session_id, std::string_view relation,
                     const Simplex& simplex);
  // Sends many simplices in one request: ids (tuple_size 0) or vertex tuples of `tuple_size`
  // input ids each; the answer's rows and item_errors are filled. At most the server's
  // max_batch_size simplices per request.
  absl::Status WriteBatch(int64_t request_id, std::string_view session_id,
                          std::string_view relation, std::span<const int64_t> values,
                          int tuple_size = 0);
  // Tells the server no more requests follow.
  absl::Status WritesDone();
  // Blocks for the next answer; nullopt when the stream has ended (then call Finish).
  std::optional<StreamItem> Read();
  // The status of the whole call (per-item errors are in the items). Call after Read returned
  // nullopt, or it cancels the call first.
  absl::Status Finish();
  // Cancels the call from any thread; pending Reads and Writes return at once.
  void Cancel();

 private:
  std::unique_ptr<Impl> impl_;
};

// ---------------------------------------------------------------------------------------------
// Jobs. Algorithm names: "topo-relations", "critical-points", "discrete-gradient",
// "morse-smale", "persistence-diagram", "topological-simplification", "diagram-distance",
// "tracking", "merge-tree", "contour-tree" ("morse_smale" works too). "diagram-distance" and
// "tracking" compare the persistence diagrams of several fields (JobOptions::fields or
// all_fields, at least two): parameters "p" (the Wasserstein order, default 2),
// "persistence_threshold" or "relative_threshold" (pairs below it left out), "essential"
// ("true": match the infinite pairs too). "merge-tree" is TTK's MergeTree: parameter "tree",
// "join" (the default) or "split"; "contour-tree" TTK's ContourTree; both take
// "persistence_threshold" or "relative_threshold" (the tree of the field simplified first) and
// their nodes and arcs read back with ResultArrays::Tree.

struct FieldResult;

// Cancels a running job from any thread: RunJob then returns CANCELLED. Copies share the same
// state, so keep one and hand a copy to JobOptions.
class CancelToken {
 public:
  CancelToken();
  // Requests cancellation (idempotent, thread-safe).
  void Cancel() const;
  bool cancelled() const;

 private:
  friend class Client;
  class Registration;
  // Calls `f` on Cancel (at once if already cancelled) until the registration is destroyed.
  std::shared_ptr<Registration> OnCancel(std::function<void()> f) const;

  struct State;
  std::shared_ptr<State> state_;
};

// How far a job has got (JobOptions::phase_progress).
struct JobProgress {
  // "faces": the mesh's edges and triangles, built (or waited for) when the job is the first
  // on the mesh to read them, once per mesh; then "run": the algorithm.
  std::string phase;
  double fraction = 0;  // of the phase, 0 to 1
  double elapsed_seconds = 0;
};

// Options of Client::RunJob.
struct JobOptions {
  // Send the result arrays (otherwise only the summary and statistics).
  bool include_arrays = true;
  // Record where the job's threads spent their time: JobResult::trace gets a Chrome
  // trace-event JSON (block relations computed per thread, consumer waits, evictions, phases)
  // to open in ui.perfetto.dev or chrome://tracing.
  bool trace = false;
  // Add the result's SHA-256 digests to the summary (its "*_sha256" keys, comparable with
  // TTK's). Off by default: on large meshes they cost a good part of the job.
  bool digests = false;
  // Called with the fraction of the algorithm's run done (0 to 1) as progress arrives, on
  // RunJob's thread.
  std::function<void(double fraction)> progress;
  // Called with every progress report, its phase included (JobProgress), on RunJob's thread.
  std::function<void(const JobProgress& report)> phase_progress;
  // Called with the job id once the server accepted the job (e.g. to CancelJob it).
  std::function<void(const std::string& job_id)> on_accepted;
  // Cancel() on (a copy of) this token cancels the job.
  CancelToken cancel;
  // Deadline of the whole job; 0: none.
  std::chrono::milliseconds timeout{0};

  // Run over these point fields of the session's mesh instead of the session's field, one
  // after the other on the session's structure (each result equals a job on that field alone),
  // or with all_fields over every floating-point field in the mesh's order (a series' time
  // order). JobResult::fields gets one FieldResult per field; `progress` runs over the whole
  // list.
  std::vector<std::string> fields;
  bool all_fields = false;
  // In a job over fields: called with each field's result (summary and arrays) as soon as it
  // arrives, on RunJob's thread, before the next field's.
  std::function<void(const FieldResult& field)> on_field;
  // In a job over fields: keep each field's result in JobResult::fields. False: they go to
  // on_field only (a long series whose arrays need not all be held at once).
  bool keep_fields = true;
};

// How far a load has got (Client::LoadMeshWithProgress).
struct LoadProgress {
  std::string phase;    // "read", "partition" (the octree) or "encode" (the static encoding)
  double fraction = 0;  // of the phase, 0 to 1
  double elapsed_seconds = 0;
};

// Options of Client::LoadMeshWithProgress.
struct LoadOptions {
  PartitionOptions partition;
  // Called as the server reports, on the calling thread; each phase at least once. An exception
  // thrown here cancels the load on the server and propagates.
  std::function<void(const LoadProgress&)> progress;
  // Cancel() on (a copy of) this token stops the load on the server, which frees what it read;
  // the call then returns CANCELLED.
  CancelToken cancel;
  // Deadline of the load; 0: ClientOptions::mesh_timeout. The server stops at the deadline.
  std::chrono::milliseconds timeout{0};
};

// ---------------------------------------------------------------------------------------------
// Uploading mesh files as their bytes (Client::UploadFile; underneath, Client::CreateUpload,
// WriteUpload, GetUpload, DeleteUpload and LoadUpload).

// A file of an upload.
struct UploadFileInfo {
  // Its path in the upload: relative, '/' between parts, no '.' or '..' part. The first file of
  // an upload is the mesh (its name: .vtu, .vtk, .vti or .pvd); a .pvd's files follow under the
  // relative paths it names them by.
  std::string path;
  int64_t size = 0;    // bytes
  std::string sha256;  // of its bytes, 64 lowercase hex digits (FileSha256)
};

// What the server holds of an upload.
struct UploadStatus {
  std::string upload_id;
  std::vector<UploadFileInfo> files;    // as announced, in order
  std::vector<int64_t> received_bytes;  // per file: the bytes held, where a write goes on from
  bool complete = false;                // every byte of every file held and its digest checked
  double expires_in_seconds = 0;        // until the server drops it if nothing is written to it
};

// How far Client::UploadFile has got.
struct UploadFileProgress {
  // "hash": reading the files for their SHA-256; "send": sending their bytes; then the load's
  // phases as LoadMeshWithProgress reports them ("read", "partition", "encode").
  std::string phase;
  double fraction = 0;  // of the phase, 0 to 1
  // "hash": the bytes hashed; "send" and later: the bytes the server holds of the files plus
  // those sent since on the current stream (after a break it goes back to what the server holds).
  int64_t bytes = 0;
  int64_t total_bytes = 0;  // the files' sizes summed
  // Bytes this call has sent, those sent again after a break included.
  int64_t sent_bytes = 0;
  int32_t resumes = 0;         // streams started again after a break so far
  std::string upload_id;       // empty while hashing
  double elapsed_seconds = 0;  // since UploadFile began
};

// Options of Client::UploadFile.
struct UploadFileOptions {
  // Called on UploadFile's thread after each chunk hashed or sent and with each report of the
  // load. An exception thrown here cancels the upload (the server drops it) and propagates.
  std::function<void(const UploadFileProgress&)> progress;
  size_t chunk_bytes = size_t{1} << 20;  // bytes read and sent at a time
  // A stream that breaks (UNAVAILABLE, DEADLINE_EXCEEDED, ...) is started again from the bytes
  // the server holds (GetUpload), after 0.2, 0.4, 0.8, 1.6, then every 2 s (+-20%); up to this
  // many times in a row without the server gaining a byte, then UploadFile gives up and keeps
  // the upload, its id in the error, for a later call to go on with (upload_id). 0: never.
  int max_resumes = 5;
  // Go on with this upload (made by CreateUpload, or kept by an UploadFile that gave up)
  // instead of creating one: its files must be those this call would announce. Empty: a new one.
  std::string upload_id;
  // Cancel() on (a copy of) this token stops the upload (the server drops it) or the load; the
  // call then returns CANCELLED.
  CancelToken cancel;
  // How the server partitions the mesh it loads. (Last, unlike in LoadOptions: GCC 12 warns,
  // wrongly, of its string "maybe used uninitialized" in options made in a call's arguments.)
  PartitionOptions partition;
};

// The SHA-256 of the file at `path`, 64 lowercase hex digits, read a MiB at a time: what
// UploadFile announces for it. NOT_FOUND if it cannot be opened.
absl::StatusOr<std::string> FileSha256(std::string_view path);

// Timings and statistics of a job.
struct JobStats {
  double run_seconds = 0;
  EngineStats engine;
  MemoryStats memory;
  // Before the run: building the mesh's edges and triangles, or waiting for their build (the
  // first job on a mesh that reads them); 0 when they were there or the algorithm reads none.
  double faces_seconds = 0;
};

// A pair of a persistence diagram (TTK's PersistenceDiagram, JobResult::PersistencePairs). A
// pair of type k is born at a critical k-cell and dies at a critical (k+1)-cell, or never dies
// (an infinite pair: one per Betti number, its death put at the global maximum). Each critical
// cell is named by its highest vertex in the vertex order, as TTK's ttkVertexScalarField.
struct PersistencePair {
  int type = 0;              // 0: minimum to 1-saddle, 1: 1-saddle to 2-saddle, 2: 2-saddle to max
  int64_t birth_vertex = 0;  // input vertex ids
  int64_t death_vertex = 0;
  double birth = 0;  // the scalar at birth_vertex
  // The scalar at death_vertex. With {"embedding": "domain"} the wire carries no death value, so
  // it is birth + persistence, which may differ from the field's value in the last bit.
  double death = 0;
  double persistence = 0;  // death - birth, as the server computed it
  bool finite = true;
};

// A merge tree (TTK's MergeTree: a merge-tree job, the join tree by default, the split tree with
// {"tree": "split"}) or a contour tree (TTK's ContourTree: a contour-tree job), read back from
// its tree_nodes/, tree_arcs/ and segmentation/ arrays (ResultArrays::Tree).
//
// The join tree follows the components of the sublevel sets as the value rises: its leaves are
// minima, its arcs run from the down node (the leaf side, lower) to the up node (the root side).
// The split tree is the join tree of the reversed field: its leaves are maxima and an arc's down
// node is its higher end. A contour tree's arcs run from the lower node (down) to the higher.
// Every vertex lies on one arc (a node's vertex on one of its arcs, as TTK's segmentation puts
// it). A connected component of the mesh has a tree of its own; a vertex in no tetrahedron is a
// tree of one node (regular) whose one arc goes from it to itself.
struct ScalarTree {
  struct Node {
    int64_t id = 0;      // NodeId: its index in `nodes`
    int64_t vertex = 0;  // VertexId: its input vertex id
    double scalar = 0;   // the field at `vertex` (float32 on the wire, as in TTK)
    // 0 minimum, 1 1-saddle, 2 2-saddle, 3 maximum, 4 degenerate (a merge of three or more, or
    // a root that is also a saddle), 5 regular (the node of a one-vertex tree).
    int critical_type = 0;
    // RegionSize and RegionSpan of one of its arcs, as TTK picks it (its only down arc, else its
    // only up arc, else its first down arc); TTK truncates a node's span to an integer.
    int64_t region_size = 0;
    double region_span = 0;
  };
  struct Arc {
    // NodeIds (indices in `nodes`) of its ends, in the tree's sense. On the wire (upNodeId,
    // downNodeId) they are relative to the first node of the arc's component; Tree() gives them
    // in the whole tree's numbering (see there).
    int64_t down_node = 0;
    int64_t up_node = 0;
    int64_t segmentation_id = 0;  // its SegmentationId, the value `segmentation` gives its vertices
    int64_t region_size = 0;      // the vertices on it, its two nodes left out
    double region_span = 0;       // the distance between its two nodes' vertices
    int64_t component = 0;        // its connected component (the server's ComponentId)
  };

  std::vector<Node> nodes;  // by NodeId
  std::vector<Arc> arcs;    // in TTK's order of the arcs
  // Per input vertex, the SegmentationId of the arc it lies on (segmentation/SegmentationId).
  std::vector<int64_t> segmentation;
  // k + 1 values for k components: the NodeIds of component i are component_offsets[i] to
  // component_offsets[i + 1] - 1.
  std::vector<int64_t> component_offsets;
};

// Result arrays by name, with typed readers: a job's own (JobResult) and, in a job over several
// fields, each field's (FieldResult).
//
// Arrays are named "<group>/<TTK array name>" (see the proto's ResultChunk):
//   critical-points:   critical_points/{Points, CriticalType, IsOnBoundary, ...}
//   discrete-gradient: critical_cells/{Points, CellDimension, CellId, ...}
//   morse-smale:       critical_points/..., separatrices/{Points, Offsets, SeparatrixType, ...},
//                      segmentation/{DescendingManifold, AscendingManifold, MorseSmaleManifold}
//   persistence-diagram: diagram/{Points, Offsets, ttkVertexScalarField, CriticalType,
//                      PairIdentifier, PairType, Persistence, Birth, IsFinite, ...} (TTK's
//                      diagram grid: two points and a line per pair, then TTK's diagonal),
//                      persistence_curve/{PairType, Persistence, NumberOfPairs};
//                      PersistencePairs() reads the pairs back from the diagram/ arrays
//   topological-simplification: simplified/{<scalar>, <scalar>_Order}
//   diagram-distance:  none of its own; each field's persistence diagram in its FieldResult
//   tracking:          tracking/{Points (k, 3) float64, Offsets int64 (a line of two points per
//                      link), Connectivity int64, TimeStep, CriticalType, Scalar, VertexId (per
//                      point), ConnectedComponentId, MatchingIdentifier, Cost, ComponentLength
//                      (per link)}, TTK's tracking output; each field's diagram in its
//                      FieldResult
//   merge-tree, contour-tree: tree_nodes/{Points, NodeId, Scalar, VertexId, CriticalType,
//                      RegionSize, RegionSpan, ComponentId} (per node), tree_arcs/{Points,
//                      Offsets, Connectivity, Scalar, ttkMaskScalarField (per point: one per
//                      node), SegmentationId, upNodeId, downNodeId, RegionSize, RegionSpan,
//                      ComponentId (per arc)}, segmentation/{SegmentationId, RegionSize,
//                      RegionSpan, RegionType} (per vertex), TTK's three outputs (ComponentId is
//                      the server's); Tree() reads them into a ScalarTree
//
//   absl::StatusOr<std::vector<int8_t>> types =
//       result->Get<int8_t>("critical_points/CriticalType");
//   absl::StatusOr<std::vector<PersistencePair>> pairs = result->PersistencePairs();
struct ResultArrays {
  std::map<std::string, Array, std::less<>> arrays;

  // The array named `name`, or nullptr.
  const Array* Find(std::string_view name) const;
  // The values of array `name` as T: NOT_FOUND without it, INVALID_ARGUMENT for another dtype.
  template <class T>
  absl::StatusOr<std::vector<T>> Get(std::string_view name) const;
  // The pairs of a persistence diagram (a persistence-diagram job, or a field of a
  // diagram-distance or tracking job), in the server's order (by the vertex order of the birth
  // vertex), without TTK's diagonal; either embedding. NOT_FOUND without the diagram/ arrays
  // (another algorithm, or JobOptions::include_arrays off); INVALID_ARGUMENT naming the array
  // when they do not hold TTK's layout (two points and one line per pair).
  absl::StatusOr<std::vector<PersistencePair>> PersistencePairs() const;
  // The tree of a merge-tree or contour-tree job (or of a field of one over several fields):
  // its nodes, its arcs with their ends as NodeIds of the whole tree, and the SegmentationId of
  // every vertex. NOT_FOUND without the tree_nodes/, tree_arcs/ and segmentation/ arrays
  // (another algorithm, or JobOptions::include_arrays off; or the ComponentId arrays, which a
  // server older than this client does not send); INVALID_ARGUMENT naming the array whose
  // shape or dtype is not TTK's, or whose ids do not fit the nodes.
  //
  // The wire gives an arc's ends relative to the first NodeId of its connected component, as
  // TTK writes them, and the server adds ComponentId per node (0, 1, ... over NodeId, each
  // component a run of NodeIds) and per arc. Tree() adds to an arc's ends the first NodeId of
  // its ComponentId (component_offsets), after checking that the nodes' ComponentId runs so and
  // that each end falls within its component's nodes.
  //
  //   absl::StatusOr<ScalarTree> tree = result->Tree();
  //   for (const ScalarTree::Arc& a : tree->arcs) {
  //     std::cout << tree->nodes[a.down_node].vertex << " -> " << tree->nodes[a.up_node].vertex
  //               << ": " << a.region_size << " vertices\n";
  //   }
  absl::StatusOr<ScalarTree> Tree() const;
};

template <class T>
absl::StatusOr<std::vector<T>> ResultArrays::Get(std::string_view name) const {
  const Array* array = Find(name);
  if (array == nullptr) {
    return absl::NotFoundError("result array '" + std::string(name) + "' not found");
  }
  return array->As<T>();
}

// One field's result in a job over several fields (JobOptions::fields): what a job on that
// field alone gives, its summary and its arrays (Get<T>, PersistencePairs, Tree as on a
// JobResult).
struct FieldResult : ResultArrays {
  std::string field;
  int32_t index = 0;  // its position in the job's list
  // Its summary as JSON: the same object as a job on that field alone.
  std::string summary_json;
  double run_seconds = 0;  // running the algorithm on it
};

// The distances between the persistence diagrams of n fields (a diagram-distance job:
// JobResult::Distances, Client::DiagramDistances). Row and column i are fields[i]; the
// matrices are n x n, row-major, symmetric with a zero diagonal. With "essential" a distance
// between diagrams with different counts of infinite pairs is infinite (in summary_json, which
// has no infinity, "Infinity").
struct DistanceMatrix {
  std::vector<std::string> fields;
  double p = 2;  // the Wasserstein order
  bool essential = false;
  std::vector<double> wasserstein;  // Wasserstein-p
  std::vector<double> bottleneck;
  std::vector<int64_t> pairs;      // pairs compared per field (after the threshold)
  std::vector<double> thresholds;  // the absolute persistence threshold per field (0: none)
  double distance_seconds = 0;

  size_t size() const { return fields.size(); }
  double Wasserstein(size_t i, size_t j) const { return wasserstein[i * fields.size() + j]; }
  double Bottleneck(size_t i, size_t j) const { return bottleneck[i * fields.size() + j]; }
};

// The summary of a tracking job (JobResult::Tracking): the persistence pairs of consecutive
// fields matched (exact Wasserstein-p matching per pair type) and chained into trajectories.
// The trajectories themselves are the tracking/ arrays (JobResult::Get).
struct TrackingSummary {
  std::vector<std::string> fields;  // the steps, in order
  double p = 2;
  int64_t trajectories = 0;
  std::vector<int64_t> trajectories_by_type;  // per pair type 0, 1, 2
  int64_t links = 0;                          // matched pairs of consecutive steps: lines
  int64_t longest = 0;                        // steps of the longest trajectory
  // The Wasserstein-p distance between step i and i + 1, and per pair type (0, 1, 2).
  std::vector<double> step_wasserstein;
  std::vector<std::vector<double>> step_wasserstein_by_type;
  double tracking_seconds = 0;
};

// The outcome of Client::RunJob: the summary, the job's own arrays (ResultArrays), the
// statistics and, in a job over several fields, each field's result.
struct JobResult : ResultArrays {
  std::string job_id;
  std::string algorithm;  // canonical name, e.g. "morse-smale"
  // The summary as a JSON object: the same keys and values as actopo-bench's "result". A job
  // over fields: {"fields": [...]}, or diagram-distance's and tracking's comparisons.
  std::string summary_json;
  JobStats stats;
  std::string trace;  // with JobOptions::trace: the trace-event JSON; else empty
  // A job over fields: one per field, in the job's order (unless JobOptions::keep_fields is
  // off).
  std::vector<FieldResult> fields;

  // The result of field `name`, or nullptr.
  const FieldResult* Field(std::string_view name) const;
  // The matrices of a diagram-distance job: NOT_FOUND for another algorithm, DATA_LOSS if the
  // summary lacks them.
  absl::StatusOr<DistanceMatrix> Distances() const;
  // The summary of a tracking job: NOT_FOUND for another algorithm, DATA_LOSS if the summary
  // lacks its figures.
  absl::StatusOr<TrackingSummary> Tracking() const;
};

// ---------------------------------------------------------------------------------------------
// The client.

// Options of Client::Connect.
struct ClientOptions {
  // Bearer token sent as `authorization: Bearer TOKEN` with every call; empty: none.
  std::string token;
  // TLS: off by default; with use_tls, tls_root_certs (PEM) or, when empty, the system roots.
  bool use_tls = false;
  std::string tls_root_certs;
  // Deadline of quick calls (info, lists, relations, stats, cancel); 0: none.
  std::chrono::milliseconds default_timeout = std::chrono::seconds(30);
  // Deadline of calls that read, partition or preprocess a mesh (load, upload, open session).
  std::chrono::milliseconds mesh_timeout = std::chrono::minutes(10);
  // When positive, Connect waits this long for the channel to be ready (UNAVAILABLE if not);
  // otherwise it connects lazily on the first call.
  std::chrono::milliseconds connect_timeout{0};
  // Largest message sent or received.
  int max_message_bytes = 256 << 20;
  // Retry the idempotent reads (GetServerInfo, ListMeshes, GetMesh, ListSessions, GetSession,
  // GetSessionStats, GetRelation, GetRelationBatch, GetUpload) when an attempt ends UNAVAILABLE: no
  // connection yet, a connection lost before the answer, or a draining server. Up to 5
  // attempts, after 0.2, 0.4, 0.8 and 1.6 s (gRPC's service config, +-20% jitter); a lost
  // connection is retried after 0.1 s, then at most every second, so a read made while the
  // server restarts succeeds once it listens again within about 2 s. Nothing that creates,
  // changes or deletes state is retried, nor any stream (Client::UploadFile resumes its uploads
  // itself: UploadFileOptions::max_resumes). False: every call is tried once.
  bool retries = true;
  // Sent with every call as the metadata `x-actopo-session`. Behind a load balancer that hashes
  // it (deploy/haproxy.cfg), every call of this client reaches the one server replica that holds
  // its meshes and sessions. Empty: $ACTOPO_AFFINITY_KEY, else a fresh random key per Client.
  // Printable ASCII (0x20-0x7E); share one key between clients that use the same sessions.
  std::string affinity_key;
};

// A connection to an actopo-server. Create with Connect; thread-safe.
class Client {
 public:
  // `target`: "HOST:PORT" (a gRPC URI such as "dns:///host:port" works too); empty: the
  // environment variable ACTOPO_SERVER.
  static absl::StatusOr<std::unique_ptr<Client>> Connect(std::string_view target,
                                                         const ClientOptions& options = {});
  Client(const Client&) = delete;
  Client& operator=(const Client&) = delete;
  ~Client();

  const std::string& target() const;
  // The affinity key this client sends (ClientOptions::affinity_key, resolved).
  const std::string& affinity_key() const;

  // Server.
  absl::StatusOr<ServerInfo> GetServerInfo();

  // Meshes.

  // Loads a file under the server's data directory, or a built-in sample as "sample:NAME"
  // (e.g. "sample:jittered:32", "sample:wavelet:64").
  absl::StatusOr<MeshInfo> LoadMesh(std::string_view path, const PartitionOptions& partition = {});
  // The same, reporting progress and cancellable:
  //
  //   actopo::client::CancelToken cancel;   // cancel.Cancel() from any thread stops the load
  //   auto mesh = client->LoadMeshWithProgress("big.vtu", {
  //       .progress = [](const actopo::client::LoadProgress& p) {
  //         std::cerr << p.phase << " " << int(100 * p.fraction) << "%\r";
  //       },
  //       .cancel = cancel});
  absl::StatusOr<MeshInfo> LoadMeshWithProgress(std::string_view path, const LoadOptions& options);
  // Loads a series (or an ensemble) given as its files under the server's data directory, in
  // step order, each with the same points and tetrahedra in the same order: one mesh, as a .pvd
  // collection of them loads, whose point fields are every file's, named "<field>_<k>" with k the
  // file's index zero-padded to the width of the last ("velocityMag_0" ... "velocityMag_3"; with
  // 12 files "_00" ... "_11"). `times`: each file's FieldInfo::time, one per path; empty: k. A
  // count other than the paths' or a non-finite time is INVALID_ARGUMENT naming files.times
  // before anything is sent. The server's errors name the file: "files.paths[k]: ..." (NOT_FOUND
  // for a missing one), or "files: step k: ..." for one whose points or tetrahedra differ.
  //
  //   auto series = client->LoadSeries(
  //       {"isabel_series_s2/isabel_02_s2_tet.vtu", "isabel_series_s2/isabel_03_s2_tet.vtu"},
  //       {2.0, 3.0});   // velocityMag_0 at time 2, velocityMag_1 at time 3
  absl::StatusOr<MeshInfo> LoadSeries(const std::vector<std::string>& paths,
                                      const std::vector<double>& times = {},
                                      const PartitionOptions& partition = {});
  // The same, reporting progress and cancellable as LoadMeshWithProgress.
  absl::StatusOr<MeshInfo> LoadSeriesWithProgress(const std::vector<std::string>& paths,
                                                  const std::vector<double>& times,
                                                  const LoadOptions& options);
  // Uploads a mesh: `points` holds x, y, z per vertex, `tetrahedra` 4 vertex ids (0-based
  // indices into the points) per tetrahedron, each field one value per vertex. Shapes are
  // checked before anything is sent; the data goes as a header with its SHA-256 and chunks.
  //
  //   std::vector<double> points = {0,0,0, 1,0,0, 0,1,0, 0,0,1};
  //   std::vector<int32_t> tets = {0, 1, 2, 3};
  //   std::vector<double> height = {0, 0, 0, 1};
  //   auto mesh = client->UploadMesh(points, tets, {{"height", height}}, {.name = "one tet"});
  absl::StatusOr<MeshInfo> UploadMesh(std::span<const double> points,
                                      std::span<const int32_t> tetrahedra,
                                      const std::vector<ScalarField>& fields = {},
                                      const UploadOptions& options = {});
  absl::StatusOr<MeshInfo> UploadMesh(std::span<const double> points,
                                      std::span<const int64_t> tetrahedra,
                                      const std::vector<ScalarField>& fields = {},
                                      const UploadOptions& options = {});
  // Uploads a mesh file of this machine as it is (.vtu, .vtk, .vti, or a .pvd with the files it
  // names) and loads it as LoadMesh loads a file of the server's data directory: the files are
  // hashed (SHA-256), announced (CreateUpload), sent a chunk at a time as they are read from
  // disk, so memory stays the same whatever their size, and checked by the server, which then
  // reads them with the reader of its data directory and drops the upload. A stream that breaks
  // goes on from the bytes the server holds (UploadFileOptions::max_resumes). A .pvd's DataSet
  // files go under the paths it names them by, relative to its folder; an absolute path or one
  // that leaves the folder ('..') is INVALID_ARGUMENT naming the entry, before anything is sent.
  // Errors: NOT_FOUND for a missing file; INVALID_ARGUMENT for another extension;
  // RESOURCE_EXHAUSTED past the server's upload budget; DATA_LOSS when the bytes the server got
  // do not hash to the digest announced; ABORTED when a file changed while being read; the
  // load's errors (a file that is not a mesh, ...) as LoadMesh gives them. On an error other
  // than giving up on a broken connection the upload is deleted, through a connection of its
  // own (on the client's, the DeleteUpload would wait behind the bytes the stopped stream left
  // queued there: seconds on a slow link).
  //
  //   auto mesh = client->UploadFile("/data/wavelet128.vtu", {
  //       .progress = [](const actopo::client::UploadFileProgress& p) {
  //         std::cerr << p.phase << " " << int(100 * p.fraction) << "%\r";
  //       }});
  //   if (mesh.ok()) std::cout << mesh->vertices << " vertices\n";   // source "upload:..."
  absl::StatusOr<MeshInfo> UploadFile(std::string_view path, const UploadFileOptions& options = {});
  // The calls under UploadFile, for uploads made by hand (bytes from memory, a file sent from
  // another process). CreateUpload announces the files (the mesh first) and reserves their
  // sizes in the server's upload budget (RESOURCE_EXHAUSTED past it). WriteUpload sends `bytes`
  // as file `file` from `offset`, which must be what the server holds of it (FAILED_PRECONDITION
  // saying how many otherwise; so after a broken stream ask GetUpload and go on from
  // received_bytes), in one stream of chunk_bytes messages; more bytes than announced are
  // INVALID_ARGUMENT, a file whose bytes do not hash to its digest DATA_LOSS, and both drop the
  // upload (then NOT_FOUND). LoadUpload loads a complete upload as LoadMeshWithProgress loads a
  // path, and the upload is gone after it, loaded or not. DeleteUpload drops one at once; the
  // server drops one nobody writes to after ServerLimits::upload_timeout_seconds.
  //
  //   std::string vtu = ...;   // a .vtu file's bytes
  //   auto sha = ...;          // their SHA-256 in lowercase hex
  //   auto upload = client->CreateUpload({{.path = "made.vtu", .size = int64_t(vtu.size()),
  //                                        .sha256 = sha}});
  //   if (!upload.ok()) return upload.status();
  //   auto written = client->WriteUpload(upload->upload_id, 0, 0, std::as_bytes(std::span(vtu)));
  //   auto mesh = client->LoadUpload(upload->upload_id);
  absl::StatusOr<UploadStatus> CreateUpload(const std::vector<UploadFileInfo>& files);
  absl::StatusOr<UploadStatus> WriteUpload(std::string_view upload_id, int32_t file, int64_t offset,
                                           std::span<const std::byte> bytes,
                                           size_t chunk_bytes = size_t{1} << 20);
  absl::StatusOr<UploadStatus> GetUpload(std::string_view upload_id);
  absl::Status DeleteUpload(std::string_view upload_id);
  absl::StatusOr<MeshInfo> LoadUpload(std::string_view upload_id, const LoadOptions& options);
  absl::StatusOr<MeshInfo> LoadUpload(std::string_view upload_id);
  absl::StatusOr<std::vector<MeshInfo>> ListMeshes();
  // With count_faces the server first builds the mesh's edges and triangles if it has not yet
  // (about a second per 10M tetrahedra; the call then gets ClientOptions::mesh_timeout), so
  // that MeshInfo::edges and triangles are set.
  absl::StatusOr<MeshInfo> GetMesh(std::string_view mesh_id, bool count_faces = false);
  // Deletes a mesh; the server frees it once no session uses it.
  absl::Status DeleteMesh(std::string_view mesh_id);
  // Adds point fields to a loaded mesh, all or none, each with one value per vertex: a header
  // with the SHA-256 of the values (AddFieldsOptions::sha256), then the values' bytes in
  // chunks, read from the spans as they go. Names must be new to the mesh (ALREADY_EXISTS) and
  // values finite (INVALID_ARGUMENT naming the field and the vertex). Returns the mesh with
  // its fields.
  //
  //   std::vector<double> doubled = ...;   // one per vertex
  //   auto mesh = client->AddFields(mesh_id, {{.name = "doubled", .values = doubled},
  //                                           {.name = "t1", .values = step1, .time = 1.0}});
  absl::StatusOr<MeshInfo> AddFields(std::string_view mesh_id,
                                     const std::vector<FieldValues>& fields,
                                     const AddFieldsOptions& options = {});
  absl::StatusOr<MeshInfo> AddField(std::string_view mesh_id, const FieldValues& field,
                                    const AddFieldsOptions& options = {});
  // A loaded mesh back as the server holds it (DownloadMesh): its points in input order, each
  // tetrahedron's vertices in the order they were given, and the point fields named in `fields`
  // in that order (or every one, with options.all_fields), in the dtype each was loaded or
  // added with. The bytes arrive in chunks of about 1 MiB, each converted into the vectors as
  // it comes, so the mesh is held once. NOT_FOUND for an unknown mesh or field ("fields[i]:
  // point field 'x' not found; point fields: ..."), INVALID_ARGUMENT for a field named twice or
  // for fields together with all_fields (before anything is sent); DATA_LOSS if the stream
  // does not hold what its header announced.
  //
  //   absl::StatusOr<actopo::client::MeshArrays> mesh =
  //       client->DownloadMesh(mesh_id, {}, {.all_fields = true});
  //   if (mesh.ok()) std::cout << mesh->vertices() << " vertices, " << mesh->fields.size() << "\n";
  absl::StatusOr<MeshArrays> DownloadMesh(std::string_view mesh_id,
                                          const std::vector<std::string>& fields = {},
                                          const DownloadOptions& options = {});
  // Deletes a point field of a mesh; sessions and jobs reading it keep it until they are done.
  // NOT_FOUND for an unknown mesh or field. Returns the mesh with its remaining fields.
  absl::StatusOr<MeshInfo> DeleteField(std::string_view mesh_id, std::string_view name);

  // Sessions.

  absl::StatusOr<SessionInfo> OpenSession(std::string_view mesh_id,
                                          const SessionOptions& options = {});
  absl::StatusOr<SessionInfo> GetSession(std::string_view session_id);
  absl::StatusOr<std::vector<SessionInfo>> ListSessions();
  // Closes a session, cancelling its running job.
  absl::Status CloseSession(std::string_view session_id);
  // Cumulative statistics of a session.
  absl::StatusOr<SessionStats> Stats(std::string_view session_id);

  // Relations.

  // One relation of one simplex: client->Relation(session_id, "vertex_star", 7).
  absl::StatusOr<std::vector<int64_t>> Relation(std::string_view session_id,
                                                std::string_view relation, const Simplex& simplex);
  // The same, with the vertex tuples of result edges and triangles.
  absl::StatusOr<RelationResult> RelationWithVertices(std::string_view session_id,
                                                      std::string_view relation,
                                                      const Simplex& simplex);
  // One relation of many simplices by id. An input that fits one request goes in a
  // GetRelationBatch call; larger ones go over one stream, in requests of up to 65536 simplices
  // written ahead of the answers, which are merged. The first failing simplex fails the call.
  absl::StatusOr<RelationCsr> RelationBatch(std::string_view session_id, std::string_view relation,
                                            std::span<const int64_t> ids);
  // One relation of many simplices by vertex tuples: `tuples` holds `tuple_size` input vertex
  // ids per simplex (2 for edges, 3 for triangles, ...).
  absl::StatusOr<RelationCsr> RelationBatchByVertices(std::string_view session_id,
                                                      std::string_view relation,
                                                      std::span<const int64_t> tuples,
                                                      int tuple_size);
  // Streams one relation over many simplices (request id = index in the input), calling
  // `on_item` on this thread for each answer as it arrives; a bad simplex gets its own error in
  // its item and the stream goes on. The returned status is that of the whole call.
  absl::Status StreamRelations(std::string_view session_id, std::string_view relation,
                               std::span<const int64_t> ids,
                               const std::function<void(StreamItem)>& on_item);
  absl::Status StreamRelations(std::string_view session_id, std::string_view relation,
                               std::span<const Simplex> simplices,
                               const std::function<void(StreamItem)>& on_item);
  // A stream to drive yourself (mixed sessions, relations and request ids).
  absl::StatusOr<std::unique_ptr<RelationStream>> OpenRelationStream();

  // Jobs.

  // Runs an algorithm on a session and waits for its result. `parameters`: e.g.
  // {{"boundary_rule", "none"}} for critical points.
  //
  //   actopo::client::CancelToken cancel;   // cancel.Cancel() from another thread stops the job
  //   auto result = client->RunJob(session_id, "morse-smale", {},
  //       {.progress = [](double f) { std::cerr << int(100 * f) << "%\r"; }, .cancel = cancel});
  absl::StatusOr<JobResult> RunJob(std::string_view session_id, std::string_view algorithm,
                                   const std::map<std::string, std::string>& parameters = {},
                                   const JobOptions& options = {});
  // Cancels a running job by id (the RunJob call then returns CANCELLED).
  absl::Status CancelJob(std::string_view job_id);
  // The distances between the persistence diagrams of several fields of the session's mesh:
  // a diagram-distance job over options.fields (every floating-point field when none are
  // given), without arrays, its summary read into a DistanceMatrix. `parameters`: "p",
  // "persistence_threshold" or "relative_threshold", "essential".
  //
  //   auto matrix = client->DiagramDistances(session_id, {{"relative_threshold", "0.01"}});
  //   if (matrix.ok()) std::cout << matrix->Wasserstein(0, 1) << "\n";
  absl::StatusOr<DistanceMatrix> DiagramDistances(
      std::string_view session_id, const std::map<std::string, std::string>& parameters = {},
      const JobOptions& options = {});

 private:
  explicit Client(std::shared_ptr<internal::Core> core);
  absl::StatusOr<int64_t> MaxBatchSize();

  std::shared_ptr<internal::Core> core_;
};

}  // namespace actopo::client

#endif  // ACTOPO_CLIENT_H_
