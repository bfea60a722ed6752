// Reads a mesh file in a child process, so that a file VTK's readers cannot survive (a crash on a
// corrupt section, an allocation far beyond what the header announced) ends the child and comes
// back as an error, never taking the server down.
//
// The child is actopo-read-mesh (server/cmd), which runs io::ReadMesh under a data-segment limit
// (RLIMIT_DATA) and sends progress and the mesh's counts back through a pipe, its arrays
// through a memory file; cancelling kills it at once.
//
//   IsolatedReadOptions options{.reader = "/usr/local/bin/actopo-read-mesh",
//                               .memory_limit_bytes = 512 << 20};
//   ASSIGN_OR_RETURN(Mesh mesh, io::ReadMeshIsolated("/data/f.vtu", options, progress));
//
// Errors: those of io::ReadMesh; InvalidArgument when the reader crashed on the file (the
// message names the signal); ResourceExhausted when it ran out of its memory limit, or when
// `admit` refused the counts; Internal when the reader could not be started.
#ifndef ACTOPO_SERVER_IO_ISOLATED_READER_H_
#define ACTOPO_SERVER_IO_ISOLATED_READER_H_

#include <cstdint>
#include <functional>
#include <string>

#include "absl/status/statusor.h"
#include "server/core/mesh.h"
#include "server/core/progress.h"

namespace actopo::io {

struct MeshShape {
  int64_t vertices = 0;
  int64_t tetrahedra = 0;
  int point_fields = 0;
};

struct IsolatedReadOptions {
  std::string reader;              // path of the actopo-read-mesh executable
  int64_t memory_limit_bytes = 0;  // the child's data limit beyond its start-up use; 0: none
  // Called with the counts the child read before the parent allocates for them; an error stops
  // the read with that error (the memory budget: files whose headers understated their size).
  std::function<absl::Status(const MeshShape&)> admit;
};

absl::StatusOr<Mesh> ReadMeshIsolated(const std::string& path, const IsolatedReadOptions& options,
                                      const Progress& progress = {});

// False in sanitizer builds, whose shadow memory the limit would count: the child runs unlimited.
bool IsolatedReadLimitsMemory();

// The child's side: reads `path` with io::ReadMesh and writes progress, then the mesh or the
// error, to `fd`, and the mesh's arrays to `arrays_fd` (descriptor 3 in actopo-read-mesh).
// Returns the process exit code. Used by actopo-read-mesh's main().
int ServeMeshRead(const std::string& path, int64_t memory_limit_bytes, int fd, int arrays_fd);

}  // namespace actopo::io

#endif  // ACTOPO_SERVER_IO_ISOLATED_READER_H_
