// Asks relation queries: one simplex by id, one by its vertices, a batch in CSR form, and an
// error with its code.
//
//   query_relations [HOST:PORT]
#include <iostream>
#include <numeric>
#include <span>
#include <string>

#include "actopo/client.h"

namespace {

void Print(const std::string& what, std::span<const int64_t> ids) {
  std::cout << what << ":";
  for (int64_t id : ids) std::cout << " " << id;
  std::cout << "\n";
}

}  // namespace

int main(int argc, char** argv) {
  absl::StatusOr<std::unique_ptr<actopo::client::Client>> connected =
      actopo::client::Client::Connect(argc > 1 ? argv[1] : "");
  if (!connected.ok()) {
    std::cerr << connected.status() << "\n";
    return 1;
  }
  actopo::client::Client& client = **connected;
  absl::StatusOr<actopo::client::MeshInfo> mesh = client.LoadMesh("sample:jittered:8");
  if (!mesh.ok()) {
    std::cerr << mesh.status() << "\n";
    return 1;
  }
  absl::StatusOr<actopo::client::SessionInfo> session =
      client.OpenSession(mesh->mesh_id, {.structure = actopo::client::Structure::kCompact});
  if (!session.ok()) {
    std::cerr << session.status() << "\n";
    return 1;
  }
  const std::string& s = session->session_id;

  // Vertices and tetrahedra by input id.
  absl::StatusOr<std::vector<int64_t>> star = client.Relation(s, "vertex_star", 0);
  if (star.ok()) Print("tetrahedra around vertex 0", *star);
  absl::StatusOr<std::vector<int64_t>> tet = client.Relation(s, "tetrahedron_vertices", 0);
  if (tet.ok()) Print("vertices of tetrahedron 0", *tet);

  // Edges and triangles by service id, or by their vertices with the vertices of the results.
  if (tet.ok()) {
    const actopo::client::Simplex edge = actopo::client::Simplex::Vertices({(*tet)[0], (*tet)[1]});
    absl::StatusOr<actopo::client::RelationResult> triangles =
        client.RelationWithVertices(s, "edge_triangles", edge);
    if (triangles.ok()) {
      Print("triangles around that tetrahedron's first edge", triangles->ids);
      Print("  their vertices, 3 each", triangles->vertices);
    }
  }

  // Many simplices at once: compressed sparse rows.
  std::vector<int64_t> vertices(5);
  std::iota(vertices.begin(), vertices.end(), 0);
  absl::StatusOr<actopo::client::RelationCsr> neighbours =
      client.RelationBatch(s, "vertex_neighbors", vertices);
  if (neighbours.ok()) {
    for (size_t i = 0; i < neighbours->size(); ++i) {
      Print("neighbours of vertex " + std::to_string(vertices[i]), (*neighbours)[i]);
    }
  }

  // Errors carry the server's code and message.
  absl::StatusOr<std::vector<int64_t>> past_the_end =
      client.Relation(s, "vertex_star", mesh->vertices);
  std::cout << "vertex " << mesh->vertices << ": " << past_the_end.status() << "\n";

  client.CloseSession(s).IgnoreError();
  client.DeleteMesh(mesh->mesh_id).IgnoreError();
  return star.ok() && tet.ok() && neighbours.ok() ? 0 : 1;
}
