#include "server/algorithms/digest.h"

#include <openssl/evp.h>

#include <algorithm>
#include <cstdio>

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
  starts_.push_back(arena_.size());
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
  auto line = [&](uint64_t start) {
    const size_t end = arena_.find('\n', start);
    return std::string_view(arena_).substr(start, end - start + 1);
  };
  // Byte order of whole lines including "\n" equals LC_ALL=C sort's order of the lines, since
  // '\n' sorts below every printable character.
  std::sort(starts_.begin(), starts_.end(),
            [&](uint64_t a, uint64_t b) { return line(a) < line(b); });
  Sha256 sha;
  for (uint64_t s : starts_) sha.Update(line(s));
  return sha.HexDigest();
}

}  // namespace actopo
