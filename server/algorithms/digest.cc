#include "server/algorithms/digest.h"

#include <openssl/evp.h>

#include <algorithm>
#include <array>
#include <bit>
#include <condition_variable>
#include <cstring>
#include <mutex>

#include "server/core/parallel.h"

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

DecimalTable::DecimalTable(int64_t n) {
  static_assert(std::endian::native == std::endian::little, "bytes 0..6 are the low bytes");
  if (n > kMaxIds) return;
  text_.resize(size_t(std::max<int64_t>(n, 0)));
  for (int64_t v = 0; v < n; ++v) {
    char digits[8] = {};
    const int length = int(WriteDecimal(digits, uint32_t(v)) - digits);
    uint64_t packed = 0;
    std::memcpy(&packed, digits, 7);
    text_[v] = packed | uint64_t(length) << 56;
  }
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

// Lines of a run of buckets of one chunk, formatted into `out`; the lines of a bucket (same first
// token) sorted by the ranks of their other tokens.
void FormatBuckets(const LineGroup& group, std::span<const uint32_t> rank,
                   std::span<const uint32_t> items, std::span<const uint32_t> bucket_end,
                   uint32_t begin, std::string& out) {
  struct Keyed {
    std::array<uint32_t, 4> key;
    uint32_t item;
    std::array<SimplexId, 4> ids;
  };
  std::vector<Keyed> ties;
  SimplexId ids[4];
  const auto emit = [&](uint32_t item, const SimplexId* tokens) {
    group.append_line(item, tokens, out);
    out += '\n';
  };
  for (const uint32_t end : bucket_end) {
    if (end - begin == 1) {
      group.sort_tokens(items[begin], ids);
      emit(items[begin], ids);
    } else if (end > begin) {
      ties.clear();
      for (uint32_t j = begin; j < end; ++j) {
        Keyed keyed{{0, 0, 0, 0}, items[j], {}};
        group.sort_tokens(items[j], keyed.ids.data());
        for (int t = 1; t < group.tokens; ++t) keyed.key[t] = rank[keyed.ids[t]];
        ties.push_back(keyed);
      }
      std::sort(ties.begin(), ties.end(),
                [](const Keyed& a, const Keyed& b) { return a.key < b.key; });
      for (const Keyed& keyed : ties) emit(keyed.item, keyed.ids.data());
    }
    begin = end;
  }
}

// Texts 0..n-1 written by `format(i, text)` on `threads` threads in any order and hashed strictly
// in order: whichever thread finishes the text next in line hashes it (and any that follow and
// are ready) while the others keep formatting, so hashing overlaps formatting. At most
// 2 * threads texts exist at once; a thread waits before starting a text that far ahead.
template <class Format>
void FormatAndHashInOrder(int64_t n, int threads, Format&& format, Sha256& sha) {
  const int64_t window = 2 * int64_t(std::max(threads, 1));
  std::vector<std::string> texts(window);
  std::mutex mu;
  std::condition_variable slot_free;
  std::vector<char> ready(window, 0);  // guarded by mu
  int64_t next = 0;                    // guarded by mu: the next text to hash
  bool hashing = false;                // guarded by mu: a thread is in the hashing loop
  ParallelFor(n, threads, [&](int64_t i, int) {
    std::string& text = texts[i % window];
    {
      std::unique_lock lock(mu);
      slot_free.wait(lock, [&] { return i < next + window; });
    }
    // The slot is ours: text i - window has been hashed and nobody touches it until ready.
    text.clear();
    format(i, text);
    std::unique_lock lock(mu);
    ready[i % window] = 1;
    if (hashing) return;  // the thread hashing will reach this text
    hashing = true;
    while (next < n && ready[next % window]) {
      const int64_t slot = next % window;
      lock.unlock();
      sha.Update(texts[slot]);
      lock.lock();
      ready[slot] = 0;
      ++next;
      slot_free.notify_all();
    }
    hashing = false;
  });
}

// One group's lines in byte order: a counting sort on the rank of the first token, filled in
// chunks of consecutive ranks holding about `chunk_items` items. Counting, filling and formatting
// run on `threads` threads (each over its own range of items, or its own run of buckets); only
// the hashing is sequential, in order, so the digest does not depend on the thread count.
void HashGroup(const LineGroup& group, std::span<const uint32_t> rank, int64_t chunk_items,
               int threads, Sha256& sha) {
  const size_t num_ranks = rank.size();
  const auto item_begin = [&](int t) { return group.items * t / threads; };
  // count[t][r]: items of thread t's range whose first token has rank r.
  std::vector<std::vector<uint32_t>> count(threads);
  ParallelFor(threads, threads, [&](int64_t t, int) {
    count[t].assign(num_ranks, 0);
    SimplexId ids[4];
    for (int64_t i = item_begin(t); i < item_begin(t + 1); ++i) {
      if (group.sort_tokens(i, ids)) ++count[t][rank[ids[0]]];
    }
  });
  const auto total_at = [&](size_t r) {
    int64_t n = 0;
    for (const auto& c : count) n += c[r];
    return n;
  };

  std::vector<uint32_t> items, bucket_end;
  for (size_t first = 0; first < num_ranks;) {
    size_t last = first + 1;
    int64_t total = total_at(first);
    while (last < num_ranks && total + total_at(last) <= chunk_items) total += total_at(last++);
    if (total == 0) {
      first = last;
      continue;
    }
    // cursor[t][k]: where thread t writes its next item of bucket k (rank first + k).
    std::vector<std::vector<uint32_t>> cursor(threads, std::vector<uint32_t>(last - first));
    bucket_end.resize(last - first);
    uint32_t position = 0;
    for (size_t k = 0; k < last - first; ++k) {
      for (int t = 0; t < threads; ++t) {
        cursor[t][k] = position;
        position += count[t][first + k];
      }
      bucket_end[k] = position;
    }
    items.resize(size_t(total));
    ParallelFor(threads, threads, [&](int64_t t, int) {
      SimplexId ids[4];
      for (int64_t i = item_begin(t); i < item_begin(t + 1); ++i) {
        if (!group.sort_tokens(i, ids)) continue;
        const size_t r = rank[ids[0]];
        if (r >= first && r < last) items[cursor[t][r - first]++] = uint32_t(i);
      }
    });
    cursor.clear();
    // Runs of buckets of about kSegmentItems items, formatted on every thread, hashed in order.
    constexpr uint32_t kSegmentItems = 1 << 15;
    std::vector<size_t> segment_start{0};
    uint32_t segment_begin = 0;
    for (size_t k = 0; k < bucket_end.size(); ++k) {
      if (bucket_end[k] - segment_begin >= kSegmentItems || k + 1 == bucket_end.size()) {
        segment_start.push_back(k + 1);
        segment_begin = bucket_end[k];
      }
    }
    FormatAndHashInOrder(
        int64_t(segment_start.size()) - 1, threads,
        [&](int64_t s, std::string& text) {
          const size_t from = segment_start[s], to = segment_start[s + 1];
          text.reserve(size_t(64) * kSegmentItems);
          FormatBuckets(group, rank, items,
                        std::span<const uint32_t>(bucket_end).subspan(from, to - from),
                        from == 0 ? 0 : bucket_end[from - 1], text);
        },
        sha);
    first = last;
  }
}

}  // namespace

std::string SortedLinesSha256(int64_t max_id, std::span<const LineGroup> groups,
                              int64_t chunk_items, int threads) {
  const std::vector<uint32_t> rank = DecimalRanks(max_id);
  if (threads <= 0) threads = std::min(DefaultThreads(), 4);
  Sha256 sha;
  for (const LineGroup& group : groups) {
    HashGroup(group, rank, std::max<int64_t>(chunk_items, 1), threads, sha);
  }
  return sha.HexDigest();
}

}  // namespace actopo
