// Mesh files through the reader as the server uses it: the header counts first (a file claiming
// more than a small budget is refused there, as the server does), then VTK's reader and our
// conversion and validation. Crashes in our code, or in VTK on what we let through, are bugs.
//
// Input: 1 byte choosing the format (.vtu, .vti), then the file's bytes.
#include <unistd.h>

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <new>
#include <string>

#include "server/io/mesh_header.h"
#include "server/io/vtk_reader.h"

// Corrupt sizes in a file make VTK allocate what they claim (up to exabytes). In the server such
// an operator new throws std::bad_alloc, which ReadMesh reports as RESOURCE_EXHAUSTED; ASan's
// operator new aborts instead. This target's operator new behaves as the server's does (ASan
// still checks every access, through malloc; run with ASAN_OPTIONS=allocator_may_return_null=1
// and alloc_dealloc_mismatch=0, since a few allocations still take ASan's operator new).
void* operator new(size_t size) {
  if (void* p = std::malloc(size == 0 ? 1 : size)) return p;
  throw std::bad_alloc();
}
void* operator new[](size_t size) { return operator new(size); }
void operator delete(void* p) noexcept { std::free(p); }
void operator delete[](void* p) noexcept { std::free(p); }
void operator delete(void* p, size_t) noexcept { std::free(p); }
void operator delete[](void* p, size_t) noexcept { std::free(p); }

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size < 1) return 0;
  // XML formats only: VTK's legacy reader dereferences null on some malformed files (a POINTS
  // section cut short, fuzz/known/), which no check of ours stops yet; see the README's known
  // limitations. Fuzzing it would only find that again.
  static const char* kExtensions[] = {".vtu", ".vti"};
  const std::string path =
      "/tmp/actopo_mesh_file_fuzzer_" + std::to_string(getpid()) + kExtensions[data[0] % 2];
  {
    std::ofstream out(path, std::ios::binary | std::ios::trunc);
    out.write(reinterpret_cast<const char*>(data + 1), std::streamsize(size - 1));
  }
  const absl::StatusOr<actopo::io::MeshCounts> counts = actopo::io::ReadMeshCounts(path);
  // The server's budget bound: about 80 bytes per tetrahedron, 48 per vertex; a fuzzing run has
  // a small one, and files without counts get the file-size bound (4 x a small file).
  if (!counts.ok() || (counts->vertices <= 100000 && counts->tetrahedra <= 100000)) {
    (void)actopo::io::ReadMesh(path);
  }
  std::remove(path.c_str());  // nothing left in /tmp once the run ends
  return 0;
}
