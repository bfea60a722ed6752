// Runs a merge-tree job for the split tree of a mesh's field and prints its largest regions: the
// arcs holding the most vertices, each from its down node (the higher end: the split tree follows
// the superlevel sets as the value falls) to its up node.
//
//   split_tree [HOST:PORT] [MESH] [COUNT]
//
// HOST:PORT defaults to $ACTOPO_SERVER; MESH is a file under the server's data directory or
// "sample:NAME" (default "sample:jittered:32"); COUNT regions are printed (default 5).
#include <algorithm>
#include <iostream>
#include <string>

#include "actopo/client.h"

int main(int argc, char** argv) {
  const std::string target = argc > 1 ? argv[1] : "";
  const std::string mesh_name = argc > 2 ? argv[2] : "sample:jittered:32";
  const size_t count = argc > 3 ? size_t(std::stoul(argv[3])) : 5;

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
  absl::StatusOr<actopo::client::SessionInfo> session = (*client)->OpenSession(mesh->mesh_id);
  absl::StatusOr<actopo::client::JobResult> result =
      session.ok() ? (*client)->RunJob(session->session_id, "merge-tree", {{"tree", "split"}})
                   : absl::StatusOr<actopo::client::JobResult>(session.status());
  absl::StatusOr<actopo::client::ScalarTree> tree =
      result.ok() ? result->Tree() : absl::StatusOr<actopo::client::ScalarTree>(result.status());
  if (tree.ok()) {
    std::cout << mesh->name << ": split tree of " << tree->nodes.size() << " nodes, "
              << tree->arcs.size() << " arcs\n";
    std::vector<actopo::client::ScalarTree::Arc> arcs = tree->arcs;
    std::sort(arcs.begin(), arcs.end(),
              [](const auto& a, const auto& b) { return a.region_size > b.region_size; });
    arcs.resize(std::min(arcs.size(), count));
    for (const actopo::client::ScalarTree::Arc& arc : arcs) {
      const actopo::client::ScalarTree::Node& down = tree->nodes[size_t(arc.down_node)];
      const actopo::client::ScalarTree::Node& up = tree->nodes[size_t(arc.up_node)];
      std::cout << "region " << arc.segmentation_id << ": " << arc.region_size
                << " vertices, from vertex " << down.vertex << " (" << down.scalar
                << ") down to vertex " << up.vertex << " (" << up.scalar << ")\n";
    }
  } else {
    std::cerr << "split tree: " << tree.status() << "\n";
  }
  // Clean up what this program made, whatever happened.
  if (session.ok()) (*client)->CloseSession(session->session_id).IgnoreError();
  (*client)->DeleteMesh(mesh->mesh_id).IgnoreError();
  return tree.ok() ? 0 : 1;
}
