// Resident memory of this process, for benchmarks and server statistics.
#ifndef ACTOPO_SERVER_CORE_PROCESS_MEMORY_H_
#define ACTOPO_SERVER_CORE_PROCESS_MEMORY_H_

#include <cstdint>

namespace actopo {

// Peak resident set size since the process started (getrusage), in bytes.
int64_t PeakRssBytes();
// Current resident set size (/proc/self/statm), in bytes; 0 if unavailable.
int64_t CurrentRssBytes();
// Bytes the allocator has handed out and not taken back: what the process's objects occupy, free
// memory the allocator keeps excluded (glibc's mallinfo2, or the sanitizer's allocator; 0
// elsewhere). Unlike RSS, it does not move with fragmentation or the allocator's caches: a leak
// check compares it, idle to idle.
int64_t HeapInUseBytes();
// Hands the allocator's free memory back to the system (glibc's malloc_trim; a no-op elsewhere).
// Freed blocks otherwise stay resident in the allocator's arenas: after a large mesh or session
// is gone, or a load stopped half way, the process would keep its peak.
void ReleaseFreeMemory();
// Gives the whole pages inside [begin, end) of a live allocation back to the system at once
// (madvise MADV_DONTNEED): they stop counting in the resident size and read as zeros after. For
// an array read for the last time while it is still allocated; a no-op where unsupported.
void ReleasePages(const void* begin, const void* end);
// Caps the allocator's arenas at `cores` (glibc's M_ARENA_MAX; a no-op elsewhere, or when the
// MALLOC_ARENA_MAX environment variable already sets it). Call first thing in main. glibc gives
// threads up to 8 arenas per core, and a relation block freed by a consumer stays in the arena of
// the producer that computed it: each arena then keeps a buffer's worth of freed blocks of its
// own, so actopo's peak would exceed compact's with the same buffer peak. With one arena per
// core, threads that run at once still rarely share one.
void LimitAllocatorArenas(int cores);

}  // namespace actopo

#endif  // ACTOPO_SERVER_CORE_PROCESS_MEMORY_H_
