#include "server/algorithms/digest.h"

#include <openssl/evp.h>

#include <algorithm>
#include <array>

namespace actopo {

struct Sha256::Context {
  EVP_MD_CTX* md = EVP_MD_CTX_new();
  ~Context() { EVP_MD_CTX_free(md); }
};

Sha256::Sha256() : context_(std::make_unique<Context>()) {
  EVP_DigestInit_ex(context_->md, EVP_sha256(), nullptr);
}

Sha256::~Sha256() = default;

void Sha256::Update(std::string_view data) {
  EVP_DigestUpdate(context_->md, data.data(), data.size());
}

std::string Sha256::HexDigest() {
  unsigned char digest[EVP_MAX_MD_SIZE];
  unsigned int length = 0;
  EVP_DigestFinal_ex(context_->md, digest, &length);
  static constexpr char kHex[] = "0123456789abcdef";
  std::string hex(2 * length, '0');
  for (unsigned int i = 0; i < length; ++i) {
    hex[2 * i] = kHex[digest[i] >> 4];
    hex[2 * i + 1] = kHex[digest[i] & 15];
  }
  return hex;
}

std::string Sha256Hex(std::string_view text) {
  Sha256 sha;
  sha.Update(text);
  return sha.HexDigest();
}

std::vector<uint32_t> DecimalRanks(int64_t n) {
  std::vector<uint32_t> rank(std::max<int64_t>(n, 0));
  if (n <= 0) return rank;
  // "0" first, then 1..n-1 in preorder of the decimal trie: 1, 10, 100, ..., 101, ..., 11, ...
  uint32_t next = 0;
  rank[0] = next++;
  int64_t x = 1;
  while (next < n) {
    rank[x] = next++;
    if (x * 10 < n) {
      x *= 10;
      continue;
    }
    while (x % 10 == 9 || x + 1 >= n) x /= 10;  // climb to the next sibling that exists
    ++x;
  }
  return rank;
}

namespace {

// One group's lines in byte order: counting sort on the rank of the first token, in chunks of
// consecutive ranks that hold at most `chunk_items` items, then the few lines sharing a first
// token sorted by the ranks of the others.
void HashGroup(const LineGroup& group, std::span<const uint32_t> rank, int64_t chunk_items,
               StreamedText& text) {
  const int64_t num_ranks = static_cast<int64_t>(rank.size());
  int shift = 0;
  while ((num_ranks >> shift) > (1 << 16)) ++shift;
  std::vector<int64_t> bins((num_ranks >> shift) + 1, 0);
  SimplexId ids[4];
  for (int64_t i = 0; i < group.items; ++i) {
    if (group.sort_tokens(i, ids)) ++bins[rank[ids[0]] >> shift];
  }

  std::vector<uint32_t> offsets, items;
  struct Keyed {
    std::array<uint32_t, 4> key;
    uint32_t item;
  };
  std::vector<Keyed> ties;
  const auto emit = [&](uint32_t item) {
    std::string& line = text.buffer();
    group.append_line(item, line);
    line.push_back('\n');
    text.Flush();
  };
  for (size_t bin = 0; bin < bins.size();) {
    size_t end = bin + 1;
    int64_t count = bins[bin];
    while (end < bins.size() && count + bins[end] <= chunk_items) count += bins[end++];
    const int64_t first = int64_t(bin) << shift;
    const int64_t last = std::min(int64_t(end) << shift, num_ranks);
    bin = end;
    if (count == 0) continue;

    offsets.assign(size_t(last - first) + 1, 0);
    for (int64_t i = 0; i < group.items; ++i) {
      if (!group.sort_tokens(i, ids)) continue;
      const int64_t r = rank[ids[0]];
      if (r >= first && r < last) ++offsets[r - first + 1];
    }
    for (size_t r = 1; r < offsets.size(); ++r) offsets[r] += offsets[r - 1];
    items.resize(size_t(count));
    for (int64_t i = 0; i < group.items; ++i) {
      if (!group.sort_tokens(i, ids)) continue;
      const int64_t r = rank[ids[0]];
      if (r >= first && r < last) items[offsets[r - first]++] = uint32_t(i);
    }
    // offsets[r] is now the end of bucket r, the start of bucket r + 1.
    uint32_t begin = 0;
    for (size_t r = 0; r + 1 < offsets.size(); ++r) {
      const uint32_t bucket_end = offsets[r];
      if (bucket_end - begin == 1) {
        emit(items[begin]);
      } else if (bucket_end > begin) {
        ties.clear();
        for (uint32_t k = begin; k < bucket_end; ++k) {
          group.sort_tokens(items[k], ids);
          Keyed keyed{{0, 0, 0, 0}, items[k]};
          for (int t = 1; t < group.tokens; ++t) keyed.key[t] = rank[ids[t]];
          ties.push_back(keyed);
        }
        std::sort(ties.begin(), ties.end(),
                  [](const Keyed& a, const Keyed& b) { return a.key < b.key; });
        for (const Keyed& k : ties) emit(k.item);
      }
      begin = bucket_end;
    }
  }
}

}  // namespace

std::string SortedLinesSha256(int64_t max_id, std::span<const LineGroup> groups,
                              int64_t chunk_items) {
  const std::vector<uint32_t> rank = DecimalRanks(max_id);
  StreamedText text;
  for (const LineGroup& group : groups) {
    HashGroup(group, rank, std::max<int64_t>(chunk_items, 1), text);
  }
  return text.HexDigest();
}

}  // namespace actopo
