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
// Sets the allocator up for a process that holds a few mesh-sized arrays at a time (glibc; a
// no-op elsewhere); call first thing in main. Two settings, each left alone when the environment
// sets it (MALLOC_ARENA_MAX, MALLOC_MMAP_THRESHOLD_ or GLIBC_TUNABLES):
// - At most `cores` arenas (M_ARENA_MAX). glibc gives threads up to 8 arenas per core, and a
//   relation block freed by a consumer stays in the arena of the producer that computed it: each
//   arena then keeps a buffer's worth of freed blocks of its own, so actopo's peak would exceed
//   compact's with the same buffer peak. With one arena per core, threads that run at once still
//   rarely share one.
// - A fixed mapping threshold (M_MMAP_THRESHOLD, kMmapThresholdBytes): blocks above it are
//   mapped on their own and go back to the system when freed, and the heap's free top is handed
//   back as soon as it passes 128 KiB. glibc's own threshold moves up to 32 MiB as large blocks are
//   freed, and its trim threshold to twice that, after which freed mesh-sized arrays (the points
//   once the blocks are known, the vertex order's sort keys) stay resident under the next ones.
//   The value trades time for a steady peak: a higher one spares page faults on fresh arrays
//   but lets arrays of a few MiB stay in a thread's arena from run to run (bench/HISTORY.md,
//   twentieth session, has the figures).
inline constexpr int64_t kMmapThresholdBytes = int64_t(4) << 20;
void ConfigureAllocator(int cores);

}  // namespace actopo

#endif  // ACTOPO_SERVER_CORE_PROCESS_MEMORY_H_
