#include "server/algorithms/digest.h"

#include <openssl/evp.h>

#include <algorithm>
#include <cstdio>
#include <thread>

#include "absl/strings/str_cat.h"

namespace actopo {
namespace {

class Sha256 {
 public:
  Sha256() : ctx_(EVP_MD_CTX_new()) { EVP_DigestInit_ex(ctx_, EVP_sha256(), nullptr); }
  ~Sha256() { EVP_MD_CTX_free(ctx_); }
  void Update(std::string_view data) { EVP_DigestUpdate(ctx_, data.data(), data.size()); }
  std::string HexDigest() {
    unsigned char digest[EVP_MAX_MD_SIZE];
    unsigned int length = 0;
    EVP_DigestFinal_ex(ctx_, digest, &length);
    std::string hex;
    char buf[3];
    for (unsigned int i = 0; i < length; ++i) {
      std::snprintf(buf, sizeof buf, "%02x", digest[i]);
      hex += buf;
    }
    return hex;
  }

 private:
  EVP_MD_CTX* ctx_;
};

}  // namespace

std::string Sha256Hex(std::string_view text) {
  Sha256 sha;
  sha.Update(text);
  return sha.HexDigest();
}

void LineDigest::Add(std::string_view line) {
  lines_.push_back({arena_.size(), uint32_t(line.size() + 1)});
  arena_.append(line);
  arena_.push_back('\n');
}

void LineDigest::AppendIds(std::string& out, std::span<const SimplexId> ids) {
  for (size_t i = 0; i < ids.size(); ++i) {
    if (i > 0) out.push_back(',');
    absl::StrAppend(&out, ids[i]);
  }
}

std::string LineDigest::InOrder() const { return Sha256Hex(arena_); }

std::string LineDigest::Sorted() {
  const char* base = arena_.data();
  // Sort on the first 16 bytes packed big-endian into two integers (cache-friendly, no pointer
  // chasing), falling back to the whole line on ties. Byte order of whole lines including
  // "\n" equals LC_ALL=C sort's order of the lines, since '\n' sorts below every printable
  // character; bytes past a line's end pack as 0, below '\n', so prefixes order first too.
  struct Keyed {
    uint64_t hi, lo;
    uint32_t line;
  };
  std::vector<Keyed> keys(lines_.size());
  for (size_t i = 0; i < lines_.size(); ++i) {
    const Line& l = lines_[i];
    uint64_t packed[2] = {0, 0};
    for (uint32_t k = 0; k < 16 && k < l.length; ++k) {
      packed[k / 8] |= uint64_t(uint8_t(base[l.start + k])) << (56 - 8 * (k % 8));
    }
    keys[i] = {packed[0], packed[1], uint32_t(i)};
  }
  const auto less = [&](const Keyed& a, const Keyed& b) {
    if (a.hi != b.hi) return a.hi < b.hi;
    if (a.lo != b.lo) return a.lo < b.lo;
    const Line& x = lines_[a.line];
    const Line& y = lines_[b.line];
    return std::string_view(base + x.start, x.length) < std::string_view(base + y.start, y.length);
  };
  const auto middle = keys.begin() + keys.size() / 2;
  std::thread first_half([&] { std::sort(keys.begin(), middle, less); });
  std::sort(middle, keys.end(), less);
  first_half.join();
  std::inplace_merge(keys.begin(), middle, keys.end(), less);
  Sha256 sha;
  for (const Keyed& k : keys) {
    const Line& l = lines_[k.line];
    sha.Update(std::string_view(base + l.start, l.length));
  }
  return sha.HexDigest();
}

}  // namespace actopo
