#include "server/cmd/flags.h"

#include "gmock/gmock.h"
#include "gtest/gtest.h"

namespace actopo {
namespace {

using ::testing::HasSubstr;

struct Parsed {
  std::string name = "x";
  int count = 1;
  double ratio = 0.2;
  bool json = false;
};

absl::Status Parse(std::vector<std::string> args, Parsed& p) {
  FlagParser flags("prog", "test");
  flags.Add("name", &p.name, "a name");
  flags.Add("count", &p.count, "a count");
  flags.Add("buffer-ratio", &p.ratio, "a ratio");
  flags.Add("json", &p.json, "json output");
  args.insert(args.begin(), "prog");
  std::vector<char*> argv;
  for (auto& a : args) argv.push_back(a.data());
  return flags.Parse(static_cast<int>(argv.size()), argv.data());
}

TEST(FlagParser, ParsesBothSpellings) {
  Parsed p;
  ASSERT_TRUE(Parse({"--name", "wavelet", "--count=4", "--buffer-ratio", "0.5", "--json"}, p).ok());
  EXPECT_EQ(p.name, "wavelet");
  EXPECT_EQ(p.count, 4);
  EXPECT_DOUBLE_EQ(p.ratio, 0.5);
  EXPECT_TRUE(p.json);
}

TEST(FlagParser, ErrorsNameTheFlagAndValue) {
  Parsed p;
  EXPECT_THAT(Parse({"--count", "many"}, p).message(), HasSubstr("--count: cannot parse 'many'"));
  EXPECT_THAT(Parse({"--colour", "red"}, p).message(), HasSubstr("unknown flag --colour"));
  EXPECT_THAT(Parse({"--name"}, p).message(), HasSubstr("--name needs a value"));
  EXPECT_THAT(Parse({"stray"}, p).message(), HasSubstr("unexpected argument 'stray'"));
}

}  // namespace
}  // namespace actopo
