// Incremental SHA-256 (OpenSSL's EVP), for the upload header's digest.
#ifndef ACTOPO_CLIENT_SRC_INTERNAL_SHA256_H_
#define ACTOPO_CLIENT_SRC_INTERNAL_SHA256_H_

#include <span>
#include <string>

#include "absl/status/statusor.h"

struct evp_md_ctx_st;

namespace actopo::client::internal {

class Sha256 {
 public:
  Sha256();
  Sha256(const Sha256&) = delete;
  Sha256& operator=(const Sha256&) = delete;
  ~Sha256();

  void Update(std::span<const std::byte> bytes);
  // Lowercase hex of the digest of everything given so far; INTERNAL if OpenSSL failed.
  absl::StatusOr<std::string> HexDigest();

 private:
  evp_md_ctx_st* context_;
  bool ok_;
};

}  // namespace actopo::client::internal

#endif  // ACTOPO_CLIENT_SRC_INTERNAL_SHA256_H_
