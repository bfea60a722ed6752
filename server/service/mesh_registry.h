// The meshes a server holds: loaded from files under the data directory, built-in samples or
// uploads; validated and partitioned once, then shared read-only by every session on them.
//
//   MeshRegistry registry({.data_dir = "/data", .max_meshes = 16}, &budget);
//   ASSIGN_OR_RETURN(auto mesh, registry.LoadFile("fertility_tet.vtu", {}));
//   registry.Delete(mesh->id);   // freed when the last session using it closes
#ifndef ACTOPO_SERVER_SERVICE_MESH_REGISTRY_H_
#define ACTOPO_SERVER_SERVICE_MESH_REGISTRY_H_

#include <atomic>
#include <filesystem>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "absl/time/time.h"
#include "server/core/mesh.h"
#include "server/core/partition.h"
#include "server/core/progress.h"
#include "server/core/sync.h"
#include "server/core/topology.h"
#include "server/io/collection.h"
#include "server/results/vertex_boundary.h"
#include "server/service/field_set.h"
#include "server/service/memory_budget.h"

namespace actopo::service {

struct LoadedMesh {
  std::string id;
  std::string name;
  std::string source;  // "file:PATH", "sample:NAME" or "upload"
  // Input ids, as loaded: the points. Its tetrahedra are freed once encoded (the topology holds
  // them, sorted, with their input ids, so a mesh does not keep them twice), and its point
  // fields move to `fields`.
  Mesh mesh;
  // The point fields: those loaded, then those added (AddFields), less those deleted. The one
  // part of a loaded mesh that changes, hence mutable; it locks itself.
  mutable FieldSet fields;
  std::shared_ptr<const Topology> topology;
  // The one thing of the input tetrahedra the topology does not keep: the order each one's
  // vertices came in (InputCorners, a byte per tetrahedron), which Morse-Smale needs for TTK's
  // triangle order. Computed once per mesh and shared by its sessions.
  std::shared_ptr<const std::vector<uint8_t>> input_corners;
  int32_t block_size = 0;  // 0 when partitioned by labels
  // IsOnBoundary of the vertices that job results ask about, shared by the mesh's sessions.
  std::shared_ptr<const VertexBoundary> vertex_boundary;
  absl::Time created;
  double load_seconds = 0;
  double partition_seconds = 0;
  Reservation reservation;  // its share of the memory budget

  int64_t bytes() const;
  // Builds the topology's edges and triangles on their first need (a job, relation query or
  // explicit session that reads them; Topology::EnsureFaces), once for every session on the
  // mesh. Their bytes come from the budget first: RESOURCE_EXHAUSTED naming the mesh when they
  // do not fit. Reports phase "faces" to `progress`, and stops, keeping nothing, when it says
  // so. A caller that finds another's build running waits for it, reporting that build's
  // fraction, until it ends or its own `progress` says stop (then CANCELLED or
  // DEADLINE_EXCEEDED, and the build goes on for the caller that started it); when that build
  // stopped, the next waiter starts one. The build is a span "faces" of `trace` when set, the
  // wait a span "wait for faces".
  absl::Status EnsureFaces(const Progress& progress = {}, Trace* trace = nullptr) const;

 private:
  mutable Mutex faces_mu_;
  mutable CondVar faces_done_;  // signalled when a build ends, built or not
  mutable bool faces_building_ ABSL_GUARDED_BY(faces_mu_) = false;
  mutable std::atomic<double> faces_fraction_{0};  // of the running build, for its waiters
  mutable Reservation faces_reservation_ ABSL_GUARDED_BY(faces_mu_);
};

struct MeshRegistryOptions {
  std::string data_dir;
  int max_meshes = 16;
  // actopo-read-mesh, to read files in a child process limited to the load's reservation (a
  // file VTK crashes on then fails the load, not the server); empty: read in this process.
  std::string reader;
};

class MeshRegistry {
 public:
  MeshRegistry(MeshRegistryOptions options, MemoryBudget* budget);

  // Loading reports phases "read", "partition" and "encode" to `progress` and stops between and
  // inside them when it says so (CANCELLED or DEADLINE_EXCEEDED); everything read or built is
  // freed and the budget released before the call returns.
  //
  // `path` is relative to the data directory; anything resolving outside it is refused.
  absl::StatusOr<std::shared_ptr<const LoadedMesh>> LoadFile(const std::string& path,
                                                             const PartitionOptions& partition,
                                                             const Progress& progress = {});
  // File `file` of an upload's folder `dir` (UploadSpool::Taken), read as LoadFile reads a file
  // of the data directory; a .pvd's files must lie in the folder. The source is "upload:FILE".
  absl::StatusOr<std::shared_ptr<const LoadedMesh>> LoadUploaded(const std::filesystem::path& dir,
                                                                 const std::string& file,
                                                                 const PartitionOptions& partition,
                                                                 const Progress& progress = {});
  // A series as a list of files (each relative to the data directory, none a .pvd): read as a
  // .pvd's steps are (io/collection.h), step k's time `times[k]` (default k). Errors name the
  // field: files.paths[k], files.times[k].
  absl::StatusOr<std::shared_ptr<const LoadedMesh>> LoadFiles(const std::vector<std::string>& paths,
                                                              const std::vector<double>& times,
                                                              const PartitionOptions& partition,
                                                              const Progress& progress = {});
  absl::StatusOr<std::shared_ptr<const LoadedMesh>> LoadSample(const std::string& name,
                                                               const PartitionOptions& partition,
                                                               const Progress& progress = {});
  // A mesh assembled elsewhere (an upload): validated and partitioned here. `reserved` (budget
  // taken before the mesh was read, possibly none) becomes the mesh's reservation, resized to
  // its estimate.
  absl::StatusOr<std::shared_ptr<const LoadedMesh>> Add(std::string name, std::string source,
                                                        Mesh mesh, double load_seconds,
                                                        const PartitionOptions& partition,
                                                        const Progress& progress = {},
                                                        Reservation reserved = {});

  absl::StatusOr<std::shared_ptr<const LoadedMesh>> Get(const std::string& id) const;
  std::vector<std::shared_ptr<const LoadedMesh>> List() const;
  absl::Status Delete(const std::string& id);
  size_t size() const;

  // Bytes a mesh of this size will take with its static encodings (for the budget).
  static int64_t EstimateBytes(int64_t vertices, int64_t tetrahedra, int point_fields = 1);
  // Fails early when `count` more meshes would exceed the limit.
  absl::Status CheckCapacity() const;

 private:
  absl::StatusOr<std::shared_ptr<const LoadedMesh>> Insert(std::unique_ptr<LoadedMesh> mesh);
  // `path` under the data directory, existing; errors name `field`.
  absl::StatusOr<std::filesystem::path> Resolve(const std::string& field,
                                                const std::string& path) const;
  static bool Within(const std::filesystem::path& root, const std::filesystem::path& file);
  // `full` (a file under `root`, shown as `path`), or the series a .pvd there lists, each of its
  // files under `root` (`where` names it in the error).
  absl::StatusOr<std::shared_ptr<const LoadedMesh>> LoadUnder(
      const std::filesystem::path& root, const std::filesystem::path& full, const std::string& path,
      std::string source, std::string_view where, const PartitionOptions& partition,
      const Progress& progress);
  // Reads one file (`series` false) or a series' `steps` under the budget, then Add. Errors
  // name the files relative to `root` and the whole as `shown`.
  absl::StatusOr<std::shared_ptr<const LoadedMesh>> Read(
      const std::vector<io::CollectionStep>& steps, bool series, std::string name,
      std::string source, const std::string& shown, const std::filesystem::path& root,
      const PartitionOptions& partition, const Progress& progress);

  const MeshRegistryOptions options_;
  MemoryBudget* budget_;
  mutable Mutex mu_;
  std::map<std::string, std::shared_ptr<const LoadedMesh>> meshes_ ABSL_GUARDED_BY(mu_);
};

}  // namespace actopo::service

#endif  // ACTOPO_SERVER_SERVICE_MESH_REGISTRY_H_
