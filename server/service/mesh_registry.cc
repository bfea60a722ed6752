#include "server/service/mesh_registry.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>

#include "absl/strings/ascii.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "absl/strings/str_replace.h"
#include "server/core/process_memory.h"
#include "server/core/status_macros.h"
#include "server/io/collection.h"
#include "server/io/isolated_reader.h"
#include "server/io/mesh_header.h"
#include "server/io/samples.h"
#include "server/io/vtk_reader.h"
#include "server/service/ids.h"

namespace actopo::service {
namespace {

// What actopo-read-mesh's data segment holds besides the mesh: VTK's XML parser buffers, its
// libraries' writable data and a few thread stacks.
constexpr int64_t kReaderOverheadBytes = int64_t(128) << 20;

double SecondsSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

}  // namespace

int64_t LoadedMesh::bytes() const {
  int64_t b = int64_t(mesh.points.capacity() * sizeof(double) +
                      mesh.tetrahedra.capacity() * sizeof(SimplexId));
  if (input_corners) b += int64_t(input_corners->capacity());
  b += fields.bytes();
  return b + (topology ? topology->bytes().total() : 0);
}

absl::Status LoadedMesh::EnsureFaces(const Progress& progress, Trace* trace) const {
  if (topology->has_faces()) return absl::OkStatus();
  {
    MutexLock lock(faces_mu_);
    // Another caller's build: wait for its end, but no longer than this caller wants to.
    auto waiting = Trace::Scope(faces_building_ ? trace : nullptr, "wait for faces", "encode");
    double reported = -1;
    while (faces_building_) {
      const double fraction = faces_fraction_.load(std::memory_order_relaxed);
      if (fraction != reported) {
        RETURN_IF_ERROR(progress.Update("faces", fraction));
        reported = fraction;
      }
      RETURN_IF_ERROR(progress.status("faces"));
      faces_done_.WaitFor(faces_mu_, std::chrono::milliseconds(20));
    }
    if (topology->has_faces()) return absl::OkStatus();
    // Edges and triangles take about 13 bytes per tetrahedron once built; while they are built,
    // their run starts in 32 bits (about 5 more) and the window being appended add to that, which
    // the reservation below covers. What they hold is what stays reserved.
    if (MemoryBudget* budget = reservation.budget(); budget != nullptr) {
      faces_reservation_ = Reservation(budget);
      RETURN_IF_ERROR(
          faces_reservation_.Resize(int64_t(topology->num_tetrahedra()) * 30,
                                    absl::StrCat("the edges and triangles of mesh '", id, "'")));
    }
    faces_building_ = true;
    faces_fraction_.store(0, std::memory_order_relaxed);
  }
  // Not under faces_mu_, so that waiters can give up (Topology::EnsureFaces has its own lock).
  const absl::Status built =
      topology->EnsureFaces(progress.AlsoReporting([this](std::string_view, double fraction) {
        faces_fraction_.store(fraction, std::memory_order_relaxed);
      }),
                            {.trace = trace});
  MutexLock lock(faces_mu_);
  faces_building_ = false;
  faces_done_.SignalAll();
  if (!built.ok()) {
    faces_reservation_ = Reservation();
    return built;
  }
  if (faces_reservation_.budget() != nullptr) {
    const TopologyBytes b = topology->bytes();
    // Shrinking never fails; growing past the estimate might, and keeps the estimate then.
    faces_reservation_.Resize(b.edges + b.triangles, "").IgnoreError();
  }
  return absl::OkStatus();
}

MeshRegistry::MeshRegistry(MeshRegistryOptions options, MemoryBudget* budget)
    : options_(std::move(options)), budget_(budget) {}

int64_t MeshRegistry::EstimateBytes(int64_t vertices, int64_t tetrahedra, int point_fields) {
  // The static encoding is about 30 bytes per tetrahedron with its faces, 16 without, the mesh
  // itself 24 + 8 per field per vertex and 16 per tetrahedron. 80 per tetrahedron besides the
  // vertices covers, with a margin, a load that would keep the mesh's tetrahedra and build its
  // faces; a load does neither (the tetrahedra are freed as they are encoded, a byte per
  // tetrahedron stays, and the faces wait for a session that reads them: LoadedMesh::EnsureFaces,
  // reserved then), so the estimate is an upper bound, and once loaded a mesh's reservation
  // shrinks to what it holds (Add).
  return vertices * (48 + 8 * std::max(point_fields - 3, 0)) + tetrahedra * 80;
}

absl::Status MeshRegistry::CheckCapacity() const {
  MutexLock lock(mu_);
  if (int(meshes_.size()) >= options_.max_meshes) {
    return absl::ResourceExhaustedError(
        absl::StrCat("meshes: the server holds its maximum of ", options_.max_meshes,
                     " meshes; delete one first (--max-meshes raises the limit)"));
  }
  return absl::OkStatus();
}

absl::StatusOr<std::filesystem::path> MeshRegistry::Resolve(const std::string& field,
                                                            const std::string& path) const {
  namespace fs = std::filesystem;
  if (path.empty()) return absl::InvalidArgumentError(absl::StrCat(field, ": empty"));
  if (options_.data_dir.empty()) {
    return absl::FailedPreconditionError(
        absl::StrCat(field, ": the server has no data directory (--data-dir)"));
  }
  std::error_code ec;
  const fs::path root = fs::weakly_canonical(options_.data_dir, ec);
  const fs::path full = fs::weakly_canonical(root / fs::path(path), ec);
  if (ec || fs::path(path).is_absolute() || !Within(root, full)) {
    return absl::InvalidArgumentError(
        absl::StrCat(field, ": '", path,
                     "' is outside the server's data directory; give a path relative to it"));
  }
  if (!fs::exists(full)) {
    return absl::NotFoundError(
        absl::StrCat(field, ": '", path, "' not found in the data directory",
                     io::IsSampleName(path)
                         ? absl::StrCat("; it names a built-in sample: load it as sample:", path)
                         : ""));
  }
  return full;
}

bool MeshRegistry::Within(const std::filesystem::path& root, const std::filesystem::path& file) {
  const auto [end, unused] = std::mismatch(root.begin(), root.end(), file.begin(), file.end());
  return end == root.end();
}

absl::StatusOr<std::shared_ptr<const LoadedMesh>> MeshRegistry::LoadFile(
    const std::string& path, const PartitionOptions& partition, const Progress& progress) {
  RETURN_IF_ERROR(CheckCapacity());
  ASSIGN_OR_RETURN(const std::filesystem::path full, Resolve("path", path));
  std::error_code ec;
  return LoadUnder(std::filesystem::weakly_canonical(options_.data_dir, ec), full, path,
                   "file:" + path, "the server's data directory", partition, progress);
}

absl::StatusOr<std::shared_ptr<const LoadedMesh>> MeshRegistry::LoadUploaded(
    const std::filesystem::path& dir, const std::string& file, const PartitionOptions& partition,
    const Progress& progress) {
  RETURN_IF_ERROR(CheckCapacity());
  std::error_code ec;
  const std::filesystem::path root = std::filesystem::weakly_canonical(dir, ec);
  return LoadUnder(root, root / file, file, "upload:" + file, "the upload", partition, progress);
}

absl::StatusOr<std::shared_ptr<const LoadedMesh>> MeshRegistry::LoadUnder(
    const std::filesystem::path& root, const std::filesystem::path& full, const std::string& path,
    std::string source, std::string_view where, const PartitionOptions& partition,
    const Progress& progress) {
  namespace fs = std::filesystem;
  if (absl::AsciiStrToLower(full.extension().string()) != ".pvd") {
    return Read({{.path = full.string()}}, /*series=*/false, full.filename().string(),
                std::move(source), path, root, partition, progress);
  }
  // A series' files, like the path itself, must lie under the root. Errors name the files as
  // the client did, not by the server's own layout.
  absl::StatusOr<std::vector<io::CollectionStep>> listed = io::ReadCollection(full);
  if (!listed.ok()) {
    return absl::Status(listed.status().code(), absl::StrReplaceAll(listed.status().message(),
                                                                    {{root.string() + "/", ""}}));
  }
  const std::vector<io::CollectionStep> steps = *std::move(listed);
  std::error_code ec;
  for (const io::CollectionStep& step : steps) {
    const fs::path file = fs::weakly_canonical(step.path, ec);
    if (ec || !Within(root, file)) {
      return absl::InvalidArgumentError(absl::StrCat("path: the series '", path, "' lists '",
                                                     fs::path(step.path).filename().string(),
                                                     "', which is outside ", std::string(where)));
    }
  }
  return Read(steps, /*series=*/true, full.filename().string(), std::move(source), path, root,
              partition, progress);
}

absl::StatusOr<std::shared_ptr<const LoadedMesh>> MeshRegistry::LoadFiles(
    const std::vector<std::string>& paths, const std::vector<double>& times,
    const PartitionOptions& partition, const Progress& progress) {
  RETURN_IF_ERROR(CheckCapacity());
  if (paths.empty())
    return absl::InvalidArgumentError("files.paths: empty; give the files of the series");
  if (!times.empty() && times.size() != paths.size()) {
    return absl::InvalidArgumentError(absl::StrCat("files.times: ", times.size(), " values for ",
                                                   paths.size(),
                                                   " paths; give one per path, or none"));
  }
  std::vector<io::CollectionStep> steps;
  for (size_t k = 0; k < paths.size(); ++k) {
    const std::string field = absl::StrCat("files.paths[", k, "]");
    ASSIGN_OR_RETURN(const std::filesystem::path full, Resolve(field, paths[k]));
    if (absl::AsciiStrToLower(full.extension().string()) == ".pvd") {
      return absl::InvalidArgumentError(absl::StrCat(
          field, ": '", paths[k], "' is a collection; load it as the path, or list its files"));
    }
    const double time = times.empty() ? double(k) : times[k];
    if (!std::isfinite(time)) {
      return absl::InvalidArgumentError(
          absl::StrCat("files.times[", k, "]: ", time, " is not finite"));
    }
    steps.push_back({.path = full.string(), .time = time});
  }
  const std::string name = std::filesystem::path(steps[0].path).filename().string();
  std::error_code ec;
  return Read(steps, /*series=*/true,
              paths.size() == 1 ? name
                                : absl::StrCat(name, " +", paths.size() - 1,
                                               paths.size() == 2 ? " file" : " files"),
              "files:" + absl::StrJoin(paths, ","), "files",
              std::filesystem::weakly_canonical(options_.data_dir, ec), partition, progress);
}

absl::StatusOr<std::shared_ptr<const LoadedMesh>> MeshRegistry::Read(
    const std::vector<io::CollectionStep>& steps, bool series, std::string name, std::string source,
    const std::string& shown, const std::filesystem::path& root, const PartitionOptions& partition,
    const Progress& progress) {
  // The budget is held before anything is read: what the mesh and its encoding will take, by
  // the counts its header announces (reading peaks below that: VTK's copy and ours, about 48
  // bytes per vertex and 57 per tetrahedron); else, for a header without counts, a bound from
  // the file's size (compressed files expand).
  std::vector<std::string> files;
  int64_t file_bytes = 0;
  for (const io::CollectionStep& step : steps) {
    std::error_code ec;
    files.push_back(step.path);
    file_bytes += int64_t(std::filesystem::file_size(step.path, ec));
  }
  absl::StatusOr<io::MeshCounts> counts = io::ReadSeriesCounts(files);
  const int64_t need =
      counts.ok() ? EstimateBytes(counts->vertices, counts->tetrahedra, counts->point_fields)
                  : file_bytes * 4;
  RETURN_IF_ERROR(budget_->Reserve(
      need, counts.ok()
                ? absl::StrCat("loading '", shown, "' (", counts->vertices, " vertices and ",
                               counts->tetrahedra, " tetrahedra by its header)")
                : absl::StrCat("loading '", shown, "'")));
  Reservation reading(budget_, need);
  const auto start = std::chrono::steady_clock::now();
  // One file: read in the isolated child when the server has one (it may use the reservation
  // and room for VTK's parser and libraries; what it sends back is admitted against the budget
  // before this process allocates for it), else here.
  const io::StepReader read_file = [&](const std::string& file, int fields_before,
                                       const Progress& step) -> absl::StatusOr<Mesh> {
    if (options_.reader.empty()) return io::ReadMesh(file, {}, step);
    const io::IsolatedReadOptions isolated{
        .reader = options_.reader,
        .memory_limit_bytes = need + kReaderOverheadBytes,
        .admit = [&](const io::MeshShape& shape) {
          const int64_t bytes =
              EstimateBytes(shape.vertices, shape.tetrahedra, fields_before + shape.point_fields);
          if (bytes <= reading.bytes()) return absl::OkStatus();
          return reading.Resize(
              bytes, absl::StrCat("loading '", shown, "' (", shape.vertices, " vertices and ",
                                  shape.tetrahedra, " tetrahedra, more than its header said)"));
        }};
    return io::ReadMeshIsolated(file, isolated, step);
  };
  absl::StatusOr<Mesh> read = series ? io::ReadSteps(steps, read_file, shown, progress)
                                     : read_file(steps[0].path, 0, progress);
  if (!read.ok()) {
    // Name the files as the client did, not by the server's own directory layout.
    return absl::Status(read.status().code(),
                        absl::StrReplaceAll(read.status().message(), {{root.string() + "/", ""}}));
  }
  Mesh mesh = std::move(*read);
  return Add(std::move(name), std::move(source), std::move(mesh), SecondsSince(start), partition,
             progress, std::move(reading));
}

absl::StatusOr<std::shared_ptr<const LoadedMesh>> MeshRegistry::LoadSample(
    const std::string& name, const PartitionOptions& partition, const Progress& progress) {
  RETURN_IF_ERROR(CheckCapacity());
  ASSIGN_OR_RETURN(const io::MeshCounts counts, io::SampleCounts(name));
  const int64_t need = EstimateBytes(counts.vertices, counts.tetrahedra, counts.point_fields);
  RETURN_IF_ERROR(budget_->Reserve(need, absl::StrCat("sample '", name, "'")));
  Reservation making(budget_, need);
  const auto start = std::chrono::steady_clock::now();
  RETURN_IF_ERROR(progress.Update("read", 0));
  ASSIGN_OR_RETURN(Mesh mesh, io::MakeSample(name));
  RETURN_IF_ERROR(progress.Update("read", 1));
  return Add(name, "sample:" + name, std::move(mesh), SecondsSince(start), partition, progress,
             std::move(making));
}

absl::StatusOr<std::shared_ptr<const LoadedMesh>> MeshRegistry::Add(
    std::string name, std::string source, Mesh mesh, double load_seconds,
    const PartitionOptions& partition, const Progress& progress, Reservation reserved) {
  RETURN_IF_ERROR(CheckCapacity());
  RETURN_IF_ERROR(ValidateMesh(mesh));
  const int64_t estimate =
      EstimateBytes(mesh.num_vertices(), mesh.num_tetrahedra(), int(mesh.point_fields.size()));
  if (reserved.bytes() == 0) reserved = Reservation(budget_);
  RETURN_IF_ERROR(reserved.Resize(estimate, absl::StrCat("mesh '", name, "'")));
  auto loaded = std::make_unique<LoadedMesh>();
  loaded->reservation = std::move(reserved);
  const auto start = std::chrono::steady_clock::now();
  PartitionOptions effective = partition;
  if (effective.bucket_capacity == 0) effective.bucket_capacity = 1000;
  RETURN_IF_ERROR(progress.Update("partition", 0));
  ASSIGN_OR_RETURN(std::vector<int32_t> blocks, ComputeBlocks(mesh, effective));
  RETURN_IF_ERROR(progress.Update("partition", 1));
  // Of the input tetrahedra the topology keeps all but their corners' order, which it takes as
  // it encodes them, handing their pages back as it goes; they are freed before the faces, the
  // encoding's larger part.
  std::vector<uint8_t> corners;
  ASSIGN_OR_RETURN(
      loaded->topology,
      Topology::Build(mesh, blocks,
                      {.tetrahedra_read =
                           [&](const Topology&) { std::vector<SimplexId>().swap(mesh.tetrahedra); },
                       .input_corners = &corners,
                       .release_tetrahedra = true,
                       // Built by the first session that reads them (LoadedMesh::EnsureFaces):
                       // critical points never does.
                       .faces = false},
                      progress));
  loaded->input_corners = std::make_shared<const std::vector<uint8_t>>(std::move(corners));
  loaded->vertex_boundary = std::make_shared<const VertexBoundary>(*loaded->topology);
  loaded->partition_seconds = SecondsSince(start);
  loaded->id = NewId("mesh");
  loaded->name = std::move(name);
  loaded->source = std::move(source);
  loaded->fields.Load(std::move(mesh.point_fields));
  mesh.point_fields.clear();
  loaded->mesh = std::move(mesh);
  loaded->block_size = effective.block_label_field.empty() ? effective.bucket_capacity : 0;
  loaded->created = absl::Now();
  loaded->load_seconds = load_seconds;
  // The estimate covered the load's peak; what stays is what the mesh holds, less than that
  // peak, so other loads and sessions get the rest. Shrinking never fails.
  if (const int64_t held = loaded->bytes(); held < loaded->reservation.bytes()) {
    loaded->reservation.Resize(held, "").IgnoreError();
  }
  return Insert(std::move(loaded));
}

absl::StatusOr<std::shared_ptr<const LoadedMesh>> MeshRegistry::Insert(
    std::unique_ptr<LoadedMesh> mesh) {
  MutexLock lock(mu_);
  if (int(meshes_.size()) >= options_.max_meshes) {
    return absl::ResourceExhaustedError(
        absl::StrCat("meshes: the server holds its maximum of ", options_.max_meshes, " meshes"));
  }
  // Its memory goes back to the system when the last session on it closes.
  std::shared_ptr<const LoadedMesh> shared(mesh.release(), [](const LoadedMesh* m) {
    delete m;
    ReleaseFreeMemory();
  });
  meshes_[shared->id] = shared;
  return shared;
}

absl::StatusOr<std::shared_ptr<const LoadedMesh>> MeshRegistry::Get(const std::string& id) const {
  MutexLock lock(mu_);
  auto it = meshes_.find(id);
  if (it == meshes_.end()) {
    return absl::NotFoundError(absl::StrCat("mesh_id: no mesh '", id, "' on this server"));
  }
  return it->second;
}

std::vector<std::shared_ptr<const LoadedMesh>> MeshRegistry::List() const {
  MutexLock lock(mu_);
  std::vector<std::shared_ptr<const LoadedMesh>> out;
  for (const auto& [id, mesh] : meshes_) out.push_back(mesh);
  return out;
}

absl::Status MeshRegistry::Delete(const std::string& id) {
  MutexLock lock(mu_);
  if (meshes_.erase(id) == 0) {
    return absl::NotFoundError(absl::StrCat("mesh_id: no mesh '", id, "' on this server"));
  }
  return absl::OkStatus();
}

size_t MeshRegistry::size() const {
  MutexLock lock(mu_);
  return meshes_.size();
}

}  // namespace actopo::service
