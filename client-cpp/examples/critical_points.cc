// Runs critical points on a mesh and prints how many of each type there are.
//
//   critical_points [HOST:PORT] [MESH]
//
// HOST:PORT defaults to $ACTOPO_SERVER; MESH is a file under the server's data directory or
// "sample:NAME" (default "sample:jittered:32").
#include <array>
#include <iostream>
#include <string>

#include "actopo/client.h"

int main(int argc, char** argv) {
  const std::string target = argc > 1 ? argv[1] : "";
  const std::string mesh_name = argc > 2 ? argv[2] : "sample:jittered:32";

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
  std::cout << mesh->name << ": " << mesh->vertices << " vertices, " << mesh->tetrahedra
            << " tetrahedra\n";

  absl::StatusOr<actopo::client::SessionInfo> session = (*client)->OpenSession(mesh->mesh_id);
  absl::StatusOr<actopo::client::JobResult> result =
      session.ok() ? (*client)->RunJob(session->session_id, "critical-points")
                   : absl::StatusOr<actopo::client::JobResult>(session.status());
  if (result.ok()) {
    // One CriticalType per critical vertex, with TTK's codes.
    absl::StatusOr<std::vector<int8_t>> types = result->Get<int8_t>("critical_points/CriticalType");
    if (types.ok()) {
      constexpr std::array<const char*, 5> kNames = {"minimum", "1-saddle", "2-saddle", "maximum",
                                                     "degenerate"};
      std::array<int, 5> counts{};
      for (int8_t t : *types) {
        if (t >= 0 && t < 5) ++counts[size_t(t)];
      }
      for (size_t i = 0; i < kNames.size(); ++i) {
        std::cout << kNames[i] << ": " << counts[i] << "\n";
      }
    }
    std::cout << "summary: " << result->summary_json << "\n";
    std::cout << "run: " << result->stats.run_seconds << " s, buffer hit rate "
              << result->stats.engine.hit_rate() << "\n";
  } else {
    std::cerr << "critical-points: " << result.status() << "\n";
  }
  // Clean up what this program made, whatever happened.
  if (session.ok()) (*client)->CloseSession(session->session_id).IgnoreError();
  (*client)->DeleteMesh(mesh->mesh_id).IgnoreError();
  return result.ok() ? 0 : 1;
}
