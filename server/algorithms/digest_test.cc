#include "server/algorithms/digest.h"

#include <algorithm>
#include <random>
#include <string>
#include <vector>

#include "absl/strings/str_cat.h"
#include "gtest/gtest.h"

namespace actopo {
namespace {

TEST(Sha256, KnownDigests) {
  EXPECT_EQ(Sha256Hex(""), "e3b0c44298fc1c149afbf4c8996fb92427ae41e4649b934ca495991b7852b855");
  // The example of ../shared/data/README.md: manifoldCheck0's critical cells.
  EXPECT_EQ(Sha256Hex("0 0\n0 9\n1 4,5\n"),
            "81bf2f9048a658a22e8d1def49435c6fdc2f2f6bfeea36d698c04a8c1a9b83fb");
  StreamedText text;
  for (const char* piece : {"0 0\n", "0 9\n", "1 4,5\n"}) {
    text.buffer() += piece;
    text.Flush();
  }
  EXPECT_EQ(text.HexDigest(), Sha256Hex("0 0\n0 9\n1 4,5\n"));
}

TEST(WriteDecimal, MatchesToString) {
  std::vector<uint32_t> values = {0, 9, 10, 99, 100, 999, 1000, 4294967295u, 1000000000u};
  for (uint32_t p = 10; p < 1000000000u; p *= 10) values.insert(values.end(), {p - 1, p, p + 1});
  std::mt19937 random(7);
  for (int i = 0; i < 10000; ++i) values.push_back(random() >> (random() % 32));
  for (uint32_t v : values) {
    char buffer[16];
    EXPECT_EQ(std::string(buffer, WriteDecimal(buffer, v)), std::to_string(v));
  }
}

TEST(DecimalTable, MatchesToStringInsideAndBeyondTheTable) {
  const DecimalTable table(12345);
  for (uint32_t v : {0u, 7u, 10u, 999u, 1000u, 12344u, 12345u, 99999999u, 4294967295u}) {
    char buffer[16 + 8];
    EXPECT_EQ(std::string(buffer, table.Write(buffer, v)), std::to_string(v)) << v;
  }
  const DecimalTable too_large(DecimalTable::kMaxIds + 1);  // falls back to WriteDecimal
  char buffer[16 + 8];
  EXPECT_EQ(std::string(buffer, too_large.Write(buffer, 8388607u)), "8388607");
}

class DecimalRanksTest : public testing::TestWithParam<int64_t> {};

TEST_P(DecimalRanksTest, OrdersIdsAsText) {
  const int64_t n = GetParam();
  std::vector<std::string> text(n);
  for (int64_t i = 0; i < n; ++i) text[i] = absl::StrCat(i);
  std::vector<int64_t> by_text(n);
  for (int64_t i = 0; i < n; ++i) by_text[i] = i;
  std::sort(by_text.begin(), by_text.end(),
            [&](int64_t a, int64_t b) { return text[a] < text[b]; });
  const std::vector<uint32_t> rank = DecimalRanks(n);
  ASSERT_EQ(rank.size(), size_t(n));
  for (int64_t r = 0; r < n; ++r) EXPECT_EQ(rank[by_text[r]], r) << "id " << by_text[r];
}

INSTANTIATE_TEST_SUITE_P(Sizes, DecimalRanksTest,
                         testing::Values(0, 1, 2, 9, 10, 11, 12, 99, 100, 101, 109, 110, 999, 1000,
                                         1001, 4321, 10000, 123457));

// Lines "<d> <ids>[ <ids>]" hashed by SortedLinesSha256 equal the text sorted and hashed.
TEST(SortedLinesSha256, EqualsSortedText) {
  std::mt19937 random(7);
  const int64_t max_id = 1000;
  std::uniform_int_distribution<SimplexId> id(0, max_id - 1);
  // Two groups: "1 a,b c" (unique sorted pairs, a value) and "2 a,b,c" (unique triples).
  std::vector<std::array<SimplexId, 3>> pairs, triples;
  for (int i = 0; i < 1500; ++i) {
    SimplexId a = id(random), b = id(random);
    if (a == b) continue;
    pairs.push_back({std::min(a, b), std::max(a, b), id(random)});
    std::array<SimplexId, 3> t{id(random), id(random), id(random)};
    std::sort(t.begin(), t.end());
    triples.push_back(t);
  }
  // A few leading ids shared by many lines (ties on the first token).
  for (SimplexId k = 0; k < 300; ++k) pairs.push_back({7, 600 + k, k});
  auto unique_by = [](auto& v, int n) {
    std::sort(v.begin(), v.end());
    v.erase(std::unique(v.begin(), v.end(),
                        [n](const auto& x, const auto& y) {
                          return std::equal(x.begin(), x.begin() + n, y.begin());
                        }),
            v.end());
    std::shuffle(v.begin(), v.end(), std::mt19937(3));
  };
  unique_by(pairs, 2);
  unique_by(triples, 3);

  std::vector<std::string> lines;
  for (const auto& p : pairs) lines.push_back(absl::StrCat("1 ", p[0], ",", p[1], " ", p[2], "\n"));
  std::vector<std::string> second;
  for (const auto& t : triples)
    second.push_back(absl::StrCat("2 ", t[0], ",", t[1], ",", t[2], "\n"));
  std::sort(lines.begin(), lines.end());
  std::sort(second.begin(), second.end());
  std::string expected_text;
  for (const auto& l : lines) expected_text += l;
  for (const auto& l : second) expected_text += l;

  std::vector<LineGroup> groups(2);
  groups[0] = {.items = int64_t(pairs.size()) + 10,  // items past the end have no line
               .tokens = 2,
               .sort_tokens =
                   [&](int64_t i, SimplexId* ids) {
                     if (i >= int64_t(pairs.size())) return false;
                     ids[0] = pairs[i][0];
                     ids[1] = pairs[i][1];
                     return true;
                   },
               .append_line =
                   [&](int64_t i, const SimplexId*, std::string& line) {
                     absl::StrAppend(&line, "1 ", pairs[i][0], ",", pairs[i][1], " ", pairs[i][2]);
                   }};
  groups[1] = {.items = int64_t(triples.size()),
               .tokens = 3,
               .sort_tokens =
                   [&](int64_t i, SimplexId* ids) {
                     std::copy(triples[i].begin(), triples[i].end(), ids);
                     return true;
                   },
               .append_line =
                   [&](int64_t i, const SimplexId*, std::string& line) {
                     absl::StrAppend(&line, "2 ", triples[i][0], ",", triples[i][1], ",",
                                     triples[i][2]);
                   }};
  const std::string expected = Sha256Hex(expected_text);
  for (int threads : {1, 2, 3}) {
    for (int64_t chunk : {int64_t(1), int64_t(17), int64_t(1000), int64_t(1) << 23}) {
      EXPECT_EQ(SortedLinesSha256(max_id, groups, chunk, threads), expected)
          << "chunk " << chunk << ", threads " << threads;
    }
  }
}

}  // namespace
}  // namespace actopo
