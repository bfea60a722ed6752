// Resident memory of this process, for benchmarks and server statistics.
#ifndef ACTOPO_SERVER_CORE_PROCESS_MEMORY_H_
#define ACTOPO_SERVER_CORE_PROCESS_MEMORY_H_

#include <cstdint>

namespace actopo {

// Peak resident set size since the process started (getrusage), in bytes.
int64_t PeakRssBytes();
// Current resident set size (/proc/self/statm), in bytes; 0 if unavailable.
int64_t CurrentRssBytes();

}  // namespace actopo

#endif  // ACTOPO_SERVER_CORE_PROCESS_MEMORY_H_
