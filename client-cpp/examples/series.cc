// Compares the persistence diagrams of every field of a mesh, such as the members of a time
// series, and prints the Wasserstein-2 and bottleneck distance matrices.
//
//   series [HOST:PORT] [MESH] [RELATIVE_THRESHOLD]
//
// HOST:PORT defaults to $ACTOPO_SERVER; MESH is a file under the server's data directory (a mesh
// with several point fields, or a .pvd collection) or "sample:NAME" (default
// "isabel_series_s2_tet.vtu"); pairs less persistent than RELATIVE_THRESHOLD times each field's
// range are left out (default 0: none).
#include <cstdio>
#include <iostream>
#include <string>

#include "actopo/client.h"

namespace {

// One matrix, a row per field, a column per field number.
void Print(const char* title, const actopo::client::DistanceMatrix& matrix, bool wasserstein) {
  std::printf("%s\n%-20s", title, "");
  for (size_t j = 0; j < matrix.size(); ++j) std::printf(" %9zu", j);
  std::printf("\n");
  for (size_t i = 0; i < matrix.size(); ++i) {
    std::printf("%2zu %-17s", i, matrix.fields[i].c_str());
    for (size_t j = 0; j < matrix.size(); ++j) {
      std::printf(" %9.4g", wasserstein ? matrix.Wasserstein(i, j) : matrix.Bottleneck(i, j));
    }
    std::printf("\n");
  }
}

}  // namespace

int main(int argc, char** argv) {
  const std::string target = argc > 1 ? argv[1] : "";
  const std::string mesh_name = argc > 2 ? argv[2] : "isabel_series_s2_tet.vtu";
  const std::string threshold = argc > 3 ? argv[3] : "0";

  absl::StatusOr<std::unique_ptr<actopo::client::Client>> client =
      actopo::client::Client::Connect(target);
  if (!client.ok()) {
    std::cerr << client.status() << "\n";
    return 1;
  }
  absl::StatusOr<actopo::client::MeshInfo> mesh = (*client)->LoadMesh(mesh_name);
  if (!mesh.ok()) {
    std::cerr << "load " << mesh_name << ": " << mesh.status() << "\n";
    return 1;
  }
  std::cout << mesh->name << ": " << mesh->vertices << " vertices, " << mesh->fields.size()
            << " fields\n";

  absl::StatusOr<actopo::client::SessionInfo> session =
      (*client)->OpenSession(mesh->mesh_id, {.structure = actopo::client::Structure::kCompact});
  // Every floating-point field of the mesh (no JobOptions::fields), in its order.
  absl::StatusOr<actopo::client::DistanceMatrix> matrix =
      session.ok() ? (*client)->DiagramDistances(
                         session->session_id, {{"relative_threshold", threshold}},
                         {.progress = [](double f) { std::cerr << int(100 * f) << "%\r"; }})
                   : absl::StatusOr<actopo::client::DistanceMatrix>(session.status());
  if (matrix.ok()) {
    for (size_t i = 0; i < matrix->size(); ++i) {
      std::cout << matrix->fields[i] << ": " << matrix->pairs[i] << " pairs compared\n";
    }
    Print("Wasserstein-2 distances:", *matrix, /*wasserstein=*/true);
    Print("bottleneck distances:", *matrix, /*wasserstein=*/false);
    std::cout << "distances computed in " << matrix->distance_seconds << " s\n";
  } else {
    std::cerr << "diagram-distance: " << matrix.status() << "\n";
  }
  // Clean up what this program made, whatever happened.
  if (session.ok()) (*client)->CloseSession(session->session_id).IgnoreError();
  (*client)->DeleteMesh(mesh->mesh_id).IgnoreError();
  return matrix.ok() ? 0 : 1;
}
