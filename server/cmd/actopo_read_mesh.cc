// actopo-read-mesh: the server's mesh file reader, run as a child process so that a file VTK's
// readers crash on ends this process, not the server (server/io/isolated_reader.h).
//
//   actopo-read-mesh PATH MEMORY_LIMIT_BYTES 3>ARRAYS    (frames to stdout; not for people)
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <string>

#include "server/io/isolated_reader.h"

int main(int argc, char** argv) {
  if (argc != 3) {
    std::fprintf(stderr,
                 "usage: actopo-read-mesh PATH MEMORY_LIMIT_BYTES\n"
                 "Started by actopo-server to read mesh files out of its own process.\n");
    return 2;
  }
  return actopo::io::ServeMeshRead(argv[1], std::atoll(argv[2]), STDOUT_FILENO, 3);
}
