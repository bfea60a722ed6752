// Uploads a mesh file of this machine to a server as its bytes (a .vtu, .vtk, .vti, or a .pvd
// with the files it names), prints the mesh the server read from it, then deletes the mesh.
//
//   upload_file [HOST:PORT] FILE [BLOCK_SIZE]
//
// HOST:PORT "" means $ACTOPO_SERVER; BLOCK_SIZE is the octree bucket capacity of the partition
// (default: the server's). The progress goes to stderr. A connection that breaks mid-way is
// resumed from the bytes the server holds.
#include <cstdio>
#include <cstdlib>
#include <iostream>
#include <string>

#include "actopo/client.h"

int main(int argc, char** argv) {
  if (argc < 3) {
    std::cerr << "usage: upload_file HOST:PORT FILE [BLOCK_SIZE]\n";
    return 2;
  }
  const std::string target = argv[1];
  const std::string file = argv[2];

  absl::StatusOr<std::unique_ptr<actopo::client::Client>> client =
      actopo::client::Client::Connect(target);
  if (!client.ok()) {
    std::cerr << client.status() << "\n";
    return 1;
  }
  actopo::client::UploadFileOptions options;
  if (argc > 3) options.partition.block_size = std::atoi(argv[3]);
  options.progress = [](const actopo::client::UploadFileProgress& p) {
    // "hash" and "send" count bytes; the load's phases ("read", "partition", "encode") follow.
    std::fprintf(stderr, "\r%-9s %3d%%  %lld of %lld bytes sent, %d resumed", p.phase.c_str(),
                 int(100 * p.fraction), static_cast<long long>(p.sent_bytes),
                 static_cast<long long>(p.total_bytes), p.resumes);
  };
  absl::StatusOr<actopo::client::MeshInfo> mesh = (*client)->UploadFile(file, options);
  std::fprintf(stderr, "\n");
  if (!mesh.ok()) {
    // e.g. INVALID_ARGUMENT for a file that is not a mesh, RESOURCE_EXHAUSTED past the server's
    // upload budget, UNAVAILABLE (with the upload's id to go on with) when the server is gone.
    std::cerr << "upload " << file << ": " << mesh.status() << "\n";
    return 1;
  }
  std::cout << mesh->name << ": " << mesh->vertices << " vertices, " << mesh->tetrahedra
            << " tetrahedra, " << mesh->blocks << " blocks\n";
  std::cout << "source: " << mesh->source << "\n";
  for (const actopo::client::FieldInfo& f : mesh->fields) {
    std::cout << "field " << f.name << " (" << actopo::client::DataTypeName(f.dtype) << ") ["
              << f.min << ", " << f.max << "]";
    if (f.time) std::cout << " at time " << *f.time;
    std::cout << "\n";
  }
  std::cout << "read in " << mesh->load_seconds << " s, partitioned in " << mesh->partition_seconds
            << " s\n";
  // Clean up what this program made.
  (*client)->DeleteMesh(mesh->mesh_id).IgnoreError();
  return 0;
}
