#include "server/io/internal/xml_tags.h"

#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "absl/strings/str_cat.h"
#include "gtest/gtest.h"
#include "server/io/test_data.h"

namespace actopo::io::internal {
namespace {

using testing::MakeTempDir;
using namespace std::string_literals;

constexpr size_t kMiB = size_t(1) << 20;

// A tag as the tests spell it: <Name key=[value] ...>, <Name .../> or </Name>.
std::string Describe(const XmlTag& tag) {
  std::string out = tag.closing ? "</" : "<";
  out += tag.name;
  for (const auto& [key, value] : tag.attributes) {
    ((out += ' ') += key) += "=[";
    (out += value) += ']';
  }
  out += tag.self_closing ? "/>" : ">";
  return out;
}

// Every tag NextXmlTag finds in `text`, then how the scan ended and where.
std::string Scan(std::string_view text) {
  std::string out;
  size_t pos = 0;
  XmlTag tag;
  while (true) {
    switch (NextXmlTag(text, pos, tag)) {
      case XmlScan::kTag: absl::StrAppend(&out, Describe(tag), " "); continue;
      case XmlScan::kEnd: return absl::StrCat(out, "end at ", pos);
      case XmlScan::kIncomplete: return absl::StrCat(out, "incomplete at ", pos);
      case XmlScan::kMalformed: return absl::StrCat(out, "malformed at ", pos);
    }
  }
}

TEST(XmlTags, Rules) {
  struct Case {
    const char* what;
    std::string_view text;
    const char* scanned;
  };
  const Case cases[] = {
      {"nothing", "", "end at 0"},
      {"text only", "1 2 3", "end at 5"},
      {"text between tags", "<X> 1 2 3 </X>\n", "<X> </X> end at 15"},
      {"tab and newline before attributes", "<Piece\tNumberOfPoints=\"8\"\n\r NumberOfCells=\"5\">",
       "<Piece NumberOfPoints=[8] NumberOfCells=[5]> end at 46"},
      {"whitespace around '='", "<X a = \"1\" b\t=\n'2'>", "<X a=[1] b=[2]> end at 19"},
      {"single quotes", "<X a='say \"hi\"'>", "<X a=[say \"hi\"]> end at 16"},
      {"'>' in a value", "<X a=\"1>2\" b='>'>", "<X a=[1>2] b=[>]> end at 17"},
      {"empty value", "<X a=\"\"/>", "<X a=[]/> end at 9"},
      {"a comment holding a tag", "<!-- <Piece NumberOfPoints=\"9\"> --><X/>", "<X/> end at 39"},
      {"declaration", "<?xml version=\"1.0\"?>\n<VTKFile>", "<VTKFile> end at 31"},
      {"space in a closing tag", "</X >", "</X> end at 5"},
      {"self-closing", "<X/><X /><X a='1'/>", "<X/> <X/> <X a=[1]/> end at 19"},
      {"duplicate attribute", "<X a=\"1\" a=\"2\">", "malformed at 0"},
      {"quote open at the end", "<X/><Y a=\"1", "<X/> incomplete at 4"},
      {"'<' at the end", "<X/><", "<X/> incomplete at 4"},
      {"'<!-' at the end", "<X/><!-", "<X/> incomplete at 4"},
      {"name at the end", "<X", "incomplete at 0"},
      {"key at the end", "<X a", "incomplete at 0"},
      {"'=' at the end", "<X a =", "incomplete at 0"},
      {"'/' at the end", "<X /", "incomplete at 0"},
      {"comment open at the end", "<X/><!-- <Y>", "<X/> incomplete at 4"},
      {"'<!-->' closes no comment", "<!--><X>", "incomplete at 0"},
      {"declaration open at the end", "<?xml ?", "incomplete at 0"},
      {"DOCTYPE", "<!DOCTYPE VTKFile>", "malformed at 0"},
      {"CDATA", "<X><![CDATA[1]]>", "<X> malformed at 3"},
      {"empty name", "<>", "malformed at 0"},
      {"space before the name", "< X>", "malformed at 0"},
      {"closing tag without a name", "</>", "malformed at 0"},
      {"attribute on a closing tag", "</X a=\"1\">", "malformed at 0"},
      {"self-closing closing tag", "</X/>", "malformed at 0"},
      {"no '='", "<X a \"1\">", "malformed at 0"},
      {"no value", "<X a>", "malformed at 0"},
      {"no quotes", "<X a=1>", "malformed at 0"},
      {"no key", "<X =\"1\">", "malformed at 0"},
      {"no whitespace before an attribute", "<X a=\"1\"b=\"2\">", "malformed at 0"},
      {"'<' in a value", "<X a=\"1<2\">", "malformed at 0"},
      {"'<' in a name", "<X<Y>", "malformed at 0"},
      {"'/' not before '>'", "<X / a=\"1\">", "malformed at 0"},
  };
  for (const Case& c : cases) EXPECT_EQ(Scan(c.text), c.scanned) << c.what;
}

TEST(XmlTags, FindAndGet) {
  const std::string_view text = "<X a=\"1\" empty=\"\"><Y>";
  size_t pos = 0;
  XmlTag tag;
  ASSERT_EQ(NextXmlTag(text, pos, tag), XmlScan::kTag);
  EXPECT_EQ(tag.Find("a"), "1");
  EXPECT_EQ(tag.Find("empty"), "");
  EXPECT_EQ(tag.Find("b"), std::nullopt);
  EXPECT_EQ(tag.Get("a"), "1");
  EXPECT_EQ(tag.Get("b"), "");
  // The next tag starts with none of the last one's attributes, in the same storage.
  const size_t capacity = tag.attributes.capacity();
  ASSERT_EQ(NextXmlTag(text, pos, tag), XmlScan::kTag);
  EXPECT_EQ(tag.name, "Y");
  EXPECT_TRUE(tag.attributes.empty());
  EXPECT_EQ(tag.attributes.capacity(), capacity);
}

TEST(XmlTags, ParseXmlInt) {
  int64_t value = 0;
  EXPECT_TRUE(ParseXmlInt(std::string_view("42"), &value));
  EXPECT_EQ(value, 42);
  EXPECT_FALSE(ParseXmlInt(std::string_view(""), &value));
  EXPECT_FALSE(ParseXmlInt(std::string_view("4x"), &value));
  int32_t narrow = 0;
  EXPECT_FALSE(ParseXmlInt(std::string_view("3000000000"), &narrow));
}

class XmlTagsInFile : public ::testing::Test {
 protected:
  std::string Write(const std::string& name, const std::string& bytes) {
    const std::string path = (dir_ / name).string();
    std::ofstream(path, std::ios::binary) << bytes;
    return path;
  }

  // The tags ForEachXmlTagInFile gives, as Describe spells them.
  absl::Status Tags(const std::string& path, std::vector<std::string>* tags) {
    return ForEachXmlTagInFile(path, [&](const XmlTag& tag) {
      tags->push_back(Describe(tag));
      return true;
    });
  }

  const std::filesystem::path dir_ = MakeTempDir("xml_tags");
};

// Whichever of its bytes ends the first block, a tag or comment reads whole.
TEST_F(XmlTagsInFile, MarkupAcrossTheBlockBoundary) {
  const std::string piece = "<Piece NumberOfPoints='8'\nNumberOfCells=\"5\">";
  for (const std::string& markup : {piece, "<!-- <Y/> -->" + piece}) {
    for (size_t before = 1; before <= markup.size(); ++before) {
      const std::string head = "<VTKFile>";
      const std::string bytes =
          head + std::string(kMiB - head.size() - before, ' ') + markup + " </VTKFile>";
      std::vector<std::string> tags;
      const absl::Status status = Tags(Write("boundary.vtu", bytes), &tags);
      ASSERT_TRUE(status.ok()) << status;
      EXPECT_EQ(tags,
                (std::vector<std::string>{
                    "<VTKFile>", "<Piece NumberOfPoints=[8] NumberOfCells=[5]>", "</VTKFile>"}))
          << markup << ", " << before << " bytes before the boundary";
    }
  }
}

// Too long wherever it starts: this one fits the buffer after two blocks.
TEST_F(XmlTagsInFile, TagLongerThanOneMiB) {
  std::vector<std::string> tags;
  const absl::Status status =
      Tags(Write("long.vtu", "<X a=\"" + std::string(kMiB, '1') + "\"/><Y/>"), &tags);
  EXPECT_EQ(status.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_EQ(status.message(), "a tag longer than 1 MiB");
  EXPECT_TRUE(tags.empty());
  // An open comment is carried as a tag is.
  const absl::Status comment =
      Tags(Write("comment.vtu", "<!-- " + std::string(3 * kMiB, '-')), &tags);
  EXPECT_EQ(comment.code(), absl::StatusCode::kInvalidArgument);
}

TEST_F(XmlTagsInFile, MalformedMarkupNamesItsByte) {
  std::vector<std::string> tags;
  const std::string before = "<X>" + std::string(kMiB + 100, ' ');
  const absl::Status status = Tags(Write("bad.vtu", before + "<Y a=\"1\"b=\"2\"/><Z/>"), &tags);
  EXPECT_EQ(status.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_EQ(status.message(), absl::StrCat("markup it cannot read at byte ", before.size()));
  EXPECT_EQ(tags, std::vector<std::string>{"<X>"});
}

// The raw appended bytes hold any byte; the scan stops at their tag.
TEST_F(XmlTagsInFile, StopsAfterTheAppendedDataTag) {
  std::vector<std::string> tags;
  const absl::Status status =
      Tags(Write("appended.vtu",
                 "<VTKFile><AppendedData encoding=\"raw\">_<<!DOCTYPE <X a=\"1\"b=\"\0<\""s +
                     std::string(3 * kMiB, '<')),
           &tags);
  ASSERT_TRUE(status.ok()) << status;
  EXPECT_EQ(tags, (std::vector<std::string>{"<VTKFile>", "<AppendedData encoding=[raw]>"}));
}

TEST_F(XmlTagsInFile, StopsWhenAsked) {
  int seen = 0;
  const absl::Status status = ForEachXmlTagInFile(Write("stop.vtu", "<A/><B/><C/>"),
                                                  [&](const XmlTag&) { return ++seen < 2; });
  ASSERT_TRUE(status.ok()) << status;
  EXPECT_EQ(seen, 2);
}

// As if the file ended before that tag: ReadMesh is the judge of a file cut short.
TEST_F(XmlTagsInFile, TagCutByTheEndOfTheFile) {
  std::vector<std::string> tags;
  const absl::Status status = Tags(Write("cut.vtu", "<A/><B c=\"1"), &tags);
  ASSERT_TRUE(status.ok()) << status;
  EXPECT_EQ(tags, std::vector<std::string>{"<A/>"});
}

TEST_F(XmlTagsInFile, MissingFileIsNotFound) {
  const std::string path = (dir_ / "missing.vtu").string();
  const absl::Status status = ForEachXmlTagInFile(path, [](const XmlTag&) { return true; });
  EXPECT_EQ(status.code(), absl::StatusCode::kNotFound);
  EXPECT_EQ(status.message(), path + ": cannot open");
}

}  // namespace
}  // namespace actopo::io::internal
