// Resident memory of this process, for benchmarks and server statistics.
#ifndef ACTOPO_SERVER_CORE_PROCESS_MEMORY_H_
#define ACTOPO_SERVER_CORE_PROCESS_MEMORY_H_

#include <cstdint>

namespace actopo {

// Peak resident set size since the process started (getrusage), in bytes.
int64_t PeakRssBytes();
// Current resident set size (/proc/self/statm), in bytes; 0 if unavailable.
int64_t CurrentRssBytes();
// Hands the allocator's free memory back to the system (glibc's malloc_trim; a no-op elsewhere).
// Freed blocks otherwise stay resident in the allocator's arenas: after a large mesh or session
// is gone, or a load stopped half way, the process would keep its peak.
void ReleaseFreeMemory();

}  // namespace actopo

#endif  // ACTOPO_SERVER_CORE_PROCESS_MEMORY_H_
