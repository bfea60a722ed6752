// SHA-256 digests of result texts (DESIGN.md "Digests"): lowercase hex of the UTF-8 text, every
// line ending in "\n". They compare directly with TTK's results in ../shared/data.
//
// The texts can be large (a 10M-tetrahedra gradient has 23M pair lines, about 1 GB), so they are
// streamed: written in pieces of about a megabyte into an incremental hash, never held whole.
//
//   Sha256 sha;
//   sha.Update("0 17\n");
//   std::string hex = sha.HexDigest();
//
//   // Lines "<d> <ids>\n" in byte order, as LC_ALL=C sort orders them, without sorting text:
//   LineGroup edges{.items = num_edges, .tokens = 2, .sort_tokens = ..., .append_line = ...};
//   std::string hex = SortedLinesSha256(num_vertices, {&edges, 1});
#ifndef ACTOPO_SERVER_ALGORITHMS_DIGEST_H_
#define ACTOPO_SERVER_ALGORITHMS_DIGEST_H_

#include <cstdint>
#include <cstring>
#include <functional>
#include <memory>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "server/core/mesh.h"

namespace actopo {

// Incremental SHA-256 (OpenSSL).
class Sha256 {
 public:
  Sha256();
  ~Sha256();
  Sha256(const Sha256&) = delete;
  Sha256& operator=(const Sha256&) = delete;
  void Update(std::string_view data);
  // Lowercase hex; call once.
  std::string HexDigest();

 private:
  struct Context;
  std::unique_ptr<Context> context_;
};

// Hex SHA-256 of a text.
std::string Sha256Hex(std::string_view text);

// A text built line by line and hashed in pieces of about a megabyte.
class StreamedText {
 public:
  // The line being appended to; end it with "\n" and call Flush() now and then (cheap).
  std::string& buffer() { return buffer_; }
  void Flush() {
    if (buffer_.size() >= kFlushBytes) FlushAll();
  }
  std::string HexDigest() {
    FlushAll();
    return sha_.HexDigest();
  }

 private:
  static constexpr size_t kFlushBytes = 1 << 20;
  void FlushAll() {
    sha_.Update(buffer_);
    buffer_.clear();
  }
  Sha256 sha_;
  std::string buffer_;
};

// Writes the decimal digits of v at p; returns the end. For formatting lines without
// allocation (a gradient digest formats tens of millions of them): the length first, then two
// digits per step from the end.
inline char* WriteDecimal(char* p, uint32_t v) {
  static constexpr char kPairs[] =
      "00010203040506070809101112131415161718192021222324252627282930313233343536373839"
      "40414243444546474849505152535455565758596061626364656667686970717273747576777879"
      "8081828384858687888990919293949596979899";
  int n = 1;
  for (uint32_t bound = 10; n < 10 && v >= bound; bound *= 10) ++n;
  char* end = p + n;
  char* q = end;
  while (v >= 100) {
    const uint32_t pair = 2 * (v % 100);
    v /= 100;
    *--q = kPairs[pair + 1];
    *--q = kPairs[pair];
  }
  if (v >= 10) {
    *--q = kPairs[2 * v + 1];
    *--q = kPairs[2 * v];
  } else {
    *--q = char('0' + v);
  }
  return end;
}

// The decimal text of every id below n, for writing ids by the ten million: an 8-byte copy
// instead of divisions. At most kMaxIds ids (64 MiB); larger ids are written by WriteDecimal.
class DecimalTable {
 public:
  static constexpr int64_t kMaxIds = int64_t(1) << 23;  // all below 10^7: 7 digits + length

  explicit DecimalTable(int64_t n);

  // Writes v at p and returns the end; may write up to 8 bytes past p whatever v's length.
  char* Write(char* p, uint32_t v) const {
    if (v >= text_.size()) return WriteDecimal(p, v);
    const uint64_t packed = text_[v];
    std::memcpy(p, &packed, 8);
    return p + (packed >> 56);  // the length is the last byte
  }

 private:
  std::vector<uint64_t> text_;  // digits in bytes 0..6 (in memory order), length in byte 7
};

// rank[i] = position of the decimal string of i among those of 0..n-1 in byte order ("0", "1",
// "10", "100", ..., "11", ...). Comparing ranks compares the ids as text.
std::vector<uint32_t> DecimalRanks(int64_t n);

// Lines that share a prefix and a layout of id tokens, e.g. every gradient pair "1 <a>,<b>
// <c>,<d>,<e>" of edges with triangles. Items 0..items-1 each give at most one line.
struct LineGroup {
  int64_t items = 0;
  // Ids that order the group's lines (1 to 4): writes the item's leading ids in the order they
  // appear in its line, returns false when the item has no line. Two lines of a group must not
  // have the same sort tokens.
  int tokens = 1;
  std::function<bool(int64_t item, SimplexId* ids)> sort_tokens;
  // Appends the item's whole line without its "\n"; `ids` are its sort tokens.
  std::function<void(int64_t item, const SimplexId* ids, std::string& line)> append_line;
};

// Hex SHA-256 of every group's lines, the groups in the given order, the lines of each group in
// byte order. Because separators (' ', ',', '\n') sort below digits and the lines of a group
// share their layout, byte order of the lines equals the order of their sort tokens compared as
// decimal text, so ids in [0, max_id) are ranked once (DecimalRanks) and no text is sorted.
// Memory: 4 + 4 * threads bytes per id (ranks and counts) plus 4 bytes per item of a chunk and a
// few megabytes of text per thread (texts are formatted on every thread and hashed in order by
// whichever thread finishes the next one, so hashing overlaps formatting); each chunk costs one
// more pass of sort_tokens over the group (a 10M-tetrahedra gradient fits one chunk). The callbacks
// are called from `threads` threads at once (0: the cores, at most 4) and must be safe for that;
// the digest does not depend on it.
std::string SortedLinesSha256(int64_t max_id, std::span<const LineGroup> groups,
                              int64_t chunk_items = int64_t(12) << 20, int threads = 0);

}  // namespace actopo

#endif  // ACTOPO_SERVER_ALGORITHMS_DIGEST_H_
