// SHA-256 digests of result texts (DESIGN.md "Digests"): lowercase hex of the UTF-8 text, every
// line ending in "\n". They compare directly with TTK's results in ../shared/data.
//
//   LineDigest lines;
//   lines.Add("0 17");              // one line, without its "\n"
//   std::string hex = lines.Sorted();   // lines in byte order, as LC_ALL=C sort
#ifndef ACTOPO_SERVER_ALGORITHMS_DIGEST_H_
#define ACTOPO_SERVER_ALGORITHMS_DIGEST_H_

#include <cstdint>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "server/core/mesh.h"

namespace actopo {

// Hex SHA-256 of a text.
std::string Sha256Hex(std::string_view text);

// Collects lines in one arena (no allocation per line) and digests them in insertion order or
// sorted in byte order.
class LineDigest {
 public:
  void Add(std::string_view line);
  // Avoids regrowing (and copying) a large arena when the size is known roughly.
  void Reserve(size_t lines, size_t bytes) {
    lines_.reserve(lines);
    arena_.reserve(bytes);
  }
  // Appends "<a>,<b>,..." (ids ascending as given) to the line being built; helpers for callers.
  static void AppendIds(std::string& out, std::span<const SimplexId> ids);
  size_t size() const { return lines_.size(); }
  std::string InOrder() const;
  // Sorts on two threads (halves, then a merge): results have tens of millions of lines.
  std::string Sorted();

 private:
  struct Line {
    uint64_t start;
    uint32_t length;  // including the "\n"
  };
  std::string arena_;
  std::vector<Line> lines_;
};

}  // namespace actopo

#endif  // ACTOPO_SERVER_ALGORITHMS_DIGEST_H_
