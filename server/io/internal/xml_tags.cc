#include "server/io/internal/xml_tags.h"

#include <cstdint>
#include <cstring>
#include <fstream>
#include <memory>

#include "absl/status/status.h"
#include "absl/strings/str_cat.h"

namespace actopo::io::internal {
namespace {

constexpr size_t kBlock = size_t(1) << 20;

bool IsSpace(char c) { return c == ' ' || c == '\t' || c == '\n' || c == '\r'; }

// Ends a name or an attribute's key. Quotes, '=' and '<' end it too, so that "<a=b>" or
// "<a<b>" is refused rather than read as a name.
bool EndsName(char c) {
  return IsSpace(c) || c == '>' || c == '/' || c == '=' || c == '<' || c == '"' || c == '\'';
}

// Whether `text` from `pos` starts with `prefix`, or ends while it still could.
enum class Prefix { kYes, kNo, kCut };
Prefix StartsWith(std::string_view text, size_t pos, std::string_view prefix) {
  const std::string_view rest = text.substr(pos, prefix.size());
  if (rest == prefix) return Prefix::kYes;
  return prefix.substr(0, rest.size()) == rest ? Prefix::kCut : Prefix::kNo;
}

}  // namespace

std::optional<std::string_view> XmlTag::Find(std::string_view key) const {
  for (const auto& [k, v] : attributes) {
    if (k == key) return v;
  }
  return std::nullopt;
}

std::string_view XmlTag::Get(std::string_view key) const {
  return Find(key).value_or(std::string_view());
}

XmlScan NextXmlTag(std::string_view text, size_t& pos, XmlTag& tag) {
  const size_t n = text.size();
  // Skips text, comments and declarations up to the '<' of a tag.
  while (true) {
    pos = text.find('<', pos);
    if (pos == std::string_view::npos) {
      pos = n;
      return XmlScan::kEnd;
    }
    std::string_view close;  // what ends the markup skipped
    size_t open_size = 0;
    if (const Prefix comment = StartsWith(text, pos, "<!--"); comment == Prefix::kYes) {
      close = "-->";
      open_size = 4;  // "<!-->" does not close itself
    } else if (comment == Prefix::kCut) {
      return XmlScan::kIncomplete;
    } else if (StartsWith(text, pos, "<?") == Prefix::kYes) {
      close = "?>";
      open_size = 2;
    } else if (StartsWith(text, pos, "<!") == Prefix::kYes) {
      return XmlScan::kMalformed;  // DOCTYPE, CDATA ("<!" at the end was cut as a comment)
    } else {
      break;
    }
    const size_t end = text.find(close, pos + open_size);
    if (end == std::string_view::npos) return XmlScan::kIncomplete;
    pos = end + close.size();
  }

  size_t i = pos + 1;
  tag.closing = i < n && text[i] == '/';
  if (tag.closing) ++i;
  const size_t name_begin = i;
  while (i < n && !EndsName(text[i])) ++i;
  if (i >= n) return XmlScan::kIncomplete;
  if (i == name_begin || !(IsSpace(text[i]) || text[i] == '>' || text[i] == '/')) {
    return XmlScan::kMalformed;
  }
  tag.name = text.substr(name_begin, i - name_begin);
  tag.self_closing = false;
  tag.attributes.clear();
  while (true) {
    const size_t space_begin = i;
    while (i < n && IsSpace(text[i])) ++i;
    if (i >= n) return XmlScan::kIncomplete;
    if (text[i] == '>') break;
    if (text[i] == '/') {
      if (i + 1 >= n) return XmlScan::kIncomplete;
      if (text[i + 1] != '>' || tag.closing) return XmlScan::kMalformed;
      tag.self_closing = true;
      ++i;
      break;
    }
    if (tag.closing || i == space_begin) return XmlScan::kMalformed;
    const size_t key_begin = i;
    while (i < n && !EndsName(text[i])) ++i;
    const std::string_view key = text.substr(key_begin, i - key_begin);
    while (i < n && IsSpace(text[i])) ++i;
    if (i >= n) return XmlScan::kIncomplete;
    if (key.empty() || text[i] != '=') return XmlScan::kMalformed;
    ++i;
    while (i < n && IsSpace(text[i])) ++i;
    if (i >= n) return XmlScan::kIncomplete;
    if (text[i] != '"' && text[i] != '\'') return XmlScan::kMalformed;
    const char quotes[] = {text[i], '<', '\0'};
    const size_t value_begin = ++i;
    const size_t value_end = text.find_first_of(quotes, value_begin);
    if (value_end == std::string_view::npos) return XmlScan::kIncomplete;
    if (text[value_end] == '<' || tag.Find(key)) return XmlScan::kMalformed;
    tag.attributes.emplace_back(key, text.substr(value_begin, value_end - value_begin));
    i = value_end + 1;
  }
  pos = i + 1;
  return XmlScan::kTag;
}

absl::Status ForEachXmlTagInFile(const std::string& path,
                                 absl::FunctionRef<bool(const XmlTag&)> fn) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return absl::NotFoundError(absl::StrCat(path, ": cannot open"));
  const absl::Status too_long = absl::InvalidArgumentError("a tag longer than 1 MiB");
  // Room for a block after a carried tag, which is at most a block long.
  const std::unique_ptr<char[]> buffer(new char[2 * kBlock]);
  size_t carried = 0;     // bytes of an unfinished tag at the buffer's start
  uint64_t at_start = 0;  // the file offset of the buffer's first byte
  XmlTag tag;
  while (true) {
    in.read(buffer.get() + carried, std::streamsize(kBlock));
    const size_t read = size_t(in.gcount());
    const std::string_view text(buffer.get(), carried + read);
    size_t pos = 0;
    XmlScan scan;
    while ((scan = NextXmlTag(text, pos, tag)) == XmlScan::kTag) {
      // The tag's '<' is just before its name (and '/'): checked whole, so that the limit
      // does not depend on where the blocks happen to cut the file.
      const size_t begin = size_t(tag.name.data() - text.data()) - (tag.closing ? 2 : 1);
      if (pos - begin > kBlock) return too_long;
      if (!fn(tag) || (tag.name == "AppendedData" && !tag.closing)) return absl::OkStatus();
    }
    if (scan == XmlScan::kMalformed) {
      return absl::InvalidArgumentError(
          absl::StrCat("markup it cannot read at byte ", at_start + pos));
    }
    carried = text.size() - pos;  // 0 at kEnd
    if (carried > kBlock) return too_long;
    if (read < kBlock) return absl::OkStatus();  // the end of the file, maybe inside a tag
    std::memmove(buffer.get(), buffer.get() + pos, carried);
    at_start += pos;
  }
}

}  // namespace actopo::io::internal
