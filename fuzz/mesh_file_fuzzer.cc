// Mesh files through the reader as the server uses it: the header counts first (a file claiming
// more than a small budget is refused there, as the server does), then VTK's reader and our
// conversion and validation. Crashes in our code, or in VTK on what we let through, are bugs.
//
// Input: 1 byte choosing the format (.vtu, .vtk, .vti), then the file's bytes.
#include <unistd.h>

#include <cstdint>
#include <fstream>
#include <string>

#include "server/io/mesh_header.h"
#include "server/io/vtk_reader.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size < 1) return 0;
  static const char* kExtensions[] = {".vtu", ".vtk", ".vti"};
  const std::string path = "/tmp/actopo_mesh_file_fuzzer_" + std::to_string(getpid()) +
                           kExtensions[data[0] % 3];
  {
    std::ofstream out(path, std::ios::binary | std::ios::trunc);
    out.write(reinterpret_cast<const char*>(data + 1), std::streamsize(size - 1));
  }
  const absl::StatusOr<actopo::io::MeshCounts> counts = actopo::io::ReadMeshCounts(path);
  // The server's budget bound: about 80 bytes per tetrahedron, 48 per vertex; a fuzzing run has
  // a small one, and files without counts get the file-size bound (4 x a small file).
  if (counts.ok() && (counts->vertices > 100000 || counts->tetrahedra > 100000)) return 0;
  (void)actopo::io::ReadMesh(path);
  return 0;
}
