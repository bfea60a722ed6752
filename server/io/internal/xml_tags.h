// Private to server/io: the one reader of the XML markup in VTK files (.vtu, .vti), for the
// header counts (mesh_header.h) and the parallel .vtu reader (appended_vtu.h). It finds tags and
// their attributes and nothing more: no tree, no entities decoded, no validation of nesting.
//
//   size_t pos = 0;
//   XmlTag tag;
//   while (NextXmlTag(text, pos, tag) == XmlScan::kTag) {
//     if (tag.name == "Piece" && !tag.closing) Use(tag.Get("NumberOfPoints"));
//   }
//
// One set of rules, which expat (VTK's parser) also holds a well-formed file to: text up to the
// next '<' is skipped, so inline ASCII or base64 data passes as text; comments (<!-- -->) and
// declarations (<? ?>) are skipped; attributes are name="value" or name='value', after
// whitespace (' ', '\t', '\n', '\r'), which may also surround the '='; a '>' may stand in a
// quoted value. What the two readers could get wrong is refused as malformed rather than
// guessed at: other <! markup (DOCTYPE, CDATA), an empty name, attributes on a closing tag, an
// attribute without '=' or quotes or whitespace before it, a '<' inside a value, and an
// attribute given twice (expat refuses that file).
#ifndef ACTOPO_SERVER_IO_INTERNAL_XML_TAGS_H_
#define ACTOPO_SERVER_IO_INTERNAL_XML_TAGS_H_

#include <cstddef>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "absl/functional/function_ref.h"
#include "absl/status/status.h"
#include "absl/strings/numbers.h"
#include "absl/strings/string_view.h"

namespace actopo::io::internal {

// One tag. Its views point into the text scanned, and are valid while that text is.
struct XmlTag {
  std::string_view name;      // "Piece"; a closing tag's without its '/'
  bool closing = false;       // </Piece>
  bool self_closing = false;  // <DataArray ... />
  // In file order, values as written (between the quotes). Cleared for every tag, its capacity
  // kept, so a scan allocates only for the longest tag.
  std::vector<std::pair<std::string_view, std::string_view>> attributes;

  std::optional<std::string_view> Find(std::string_view key) const;
  std::string_view Get(std::string_view key) const;  // "" when absent
};

enum class XmlScan {
  kTag,         // `tag` holds the next tag; `pos` is just past its '>'
  kEnd,         // no '<' left in the text; `pos` is its size
  kIncomplete,  // the text ends inside a tag, comment or declaration; `pos` is on its '<'
  kMalformed,   // markup these rules refuse; `pos` is on its '<'
};

// The next tag of `text` from `pos`. `tag` is meaningful only on kTag. A caller reading a file
// in blocks keeps the text from `pos` on kIncomplete and scans it again with the next block.
XmlScan NextXmlTag(std::string_view text, size_t& pos, XmlTag& tag);

// An attribute's value as an integer, as absl::SimpleAtoi reads it (absl's string_view is its
// own type in this Abseil, not std::string_view).
template <class T>
bool ParseXmlInt(std::string_view text, T* out) {
  return absl::SimpleAtoi(absl::string_view(text.data(), text.size()), out);
}

// Calls fn(tag) for every tag of the file at `path`, in order, until fn returns false or after
// the opening AppendedData tag, whose raw bytes follow (they may hold any byte, '<' included).
// The file is read in blocks of 1 MiB and nothing is kept whole: a tag cut by a block's end is
// carried to the next, so a tag longer than 1 MiB, or a comment or declaration still open 1 MiB
// on, is an error. A tag cut by the end of the file ends the scan without error: the tags
// before it were seen, and ReadMesh is the judge of a file cut short.
//
// NotFound "<path>: cannot open"; InvalidArgument with the reason only ("a tag longer than
// 1 MiB", "markup it cannot read at byte N"), which the caller words with the path.
absl::Status ForEachXmlTagInFile(const std::string& path,
                                 absl::FunctionRef<bool(const XmlTag&)> fn);

}  // namespace actopo::io::internal

#endif  // ACTOPO_SERVER_IO_INTERNAL_XML_TAGS_H_
