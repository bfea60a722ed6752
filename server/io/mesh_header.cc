#include "server/io/mesh_header.h"

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <optional>
#include <string_view>
#include <vector>

#include "absl/strings/ascii.h"
#include "absl/strings/match.h"
#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_split.h"
#include "absl/strings/string_view.h"
#include "server/core/status_macros.h"
#include "server/io/collection.h"
#include "server/io/internal/xml_tags.h"

namespace actopo::io {
namespace {

absl::Status NoCounts(const std::string& path, absl::string_view why) {
  return absl::InvalidArgumentError(absl::StrCat(path, ": no counts in the header: ", why));
}

// A scan's error in this file's words: its reason, after the path, is why there are no counts.
absl::Status ScanError(const std::string& path, const absl::Status& status) {
  return absl::IsInvalidArgument(status) ? NoCounts(path, status.message()) : status;
}

std::optional<int64_t> IntAttribute(const internal::XmlTag& tag, std::string_view name) {
  const std::optional<std::string_view> text = tag.Find(name);
  int64_t value = 0;
  if (!text || !internal::ParseXmlInt(*text, &value) || value < 0) return std::nullopt;
  return value;
}

// Counts the 1-component DataArray elements of the first PointData element.
struct PointFieldCounter {
  int fields = 0;
  int state = 0;  // 0: before the first PointData, 1: inside it, 2: after it

  void See(const internal::XmlTag& tag) {
    if (state == 0 && tag.name == "PointData" && !tag.closing) {
      state = tag.self_closing ? 2 : 1;
    } else if (state == 1 && tag.name == "PointData" && tag.closing) {
      state = 2;
    } else if (state == 1 && tag.name == "DataArray" && !tag.closing) {
      const std::optional<std::string_view> components = tag.Find("NumberOfComponents");
      int value = 0;
      fields += !components || (internal::ParseXmlInt(*components, &value) && value == 1);
    }
  }
};

absl::StatusOr<MeshCounts> UnstructuredGridCounts(const std::string& path) {
  MeshCounts counts;
  int pieces = 0;
  PointFieldCounter fields;
  absl::Status bad;
  const absl::Status read = internal::ForEachXmlTagInFile(path, [&](const internal::XmlTag& tag) {
    fields.See(tag);
    if (tag.name != "Piece" || tag.closing) return true;
    const std::optional<int64_t> points = IntAttribute(tag, "NumberOfPoints");
    const std::optional<int64_t> cells = IntAttribute(tag, "NumberOfCells");
    if (!points || !cells) {
      bad = NoCounts(path, "a Piece without NumberOfPoints and NumberOfCells");
      return false;
    }
    counts.vertices += *points;
    counts.tetrahedra += *cells;
    ++pieces;
    return true;
  });
  if (!read.ok()) return ScanError(path, read);
  if (!bad.ok()) return bad;
  if (pieces == 0) return NoCounts(path, "no Piece element");
  counts.point_fields = fields.fields;
  return counts;
}

absl::StatusOr<MeshCounts> ImageDataCounts(const std::string& path) {
  std::optional<MeshCounts> counts;
  PointFieldCounter fields;
  const absl::Status read = internal::ForEachXmlTagInFile(path, [&](const internal::XmlTag& tag) {
    fields.See(tag);
    if (!counts && tag.name == "ImageData" && !tag.closing) {
      const std::optional<std::string_view> extent = tag.Find("WholeExtent");
      if (!extent) return false;
      const std::vector<absl::string_view> parts =
          absl::StrSplit(absl::string_view(extent->data(), extent->size()),
                         absl::ByAnyChar(" \t\n\r"), absl::SkipEmpty());
      int64_t e[6];
      if (parts.size() != 6) return false;
      for (int i = 0; i < 6; ++i) {
        if (!absl::SimpleAtoi(parts[i], &e[i])) return false;
      }
      counts = MeshCounts();
      counts->vertices = 1;
      counts->tetrahedra = 5;
      for (int axis = 0; axis < 3; ++axis) {
        const int64_t cells = std::max<int64_t>(e[2 * axis + 1] - e[2 * axis], 0);
        counts->vertices *= cells + 1;
        counts->tetrahedra *= cells;
      }
    }
    return true;
  });
  if (!read.ok()) return ScanError(path, read);
  if (!counts) return NoCounts(path, "no ImageData element with a WholeExtent");
  counts->point_fields = fields.fields;
  return *counts;
}

// Bytes of one value of a legacy type name ("float", "double", "int", "vtktypeint64", ...).
int LegacyTypeBytes(absl::string_view type) {
  const std::string t = absl::AsciiStrToLower(type);
  if (t == "float" || t == "int" || t == "unsigned_int" || t == "vtktypeint32") return 4;
  if (t == "double" || t == "long" || t == "unsigned_long" || t == "vtktypeint64" ||
      t == "vtkidtype") {
    return 8;
  }
  if (t == "short" || t == "unsigned_short") return 2;
  if (t == "char" || t == "unsigned_char" || t == "bit") return 1;
  return 0;
}

absl::StatusOr<MeshCounts> LegacyCounts(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return absl::NotFoundError(absl::StrCat(path, ": cannot open"));
  std::string line;
  std::getline(in, line);  // # vtk DataFile Version x.y
  std::getline(in, line);  // title
  std::getline(in, line);
  const bool binary = absl::StripAsciiWhitespace(line) == "BINARY";
  MeshCounts counts;
  bool have_points = false;
  while (std::getline(in, line)) {
    const std::vector<absl::string_view> words =
        absl::StrSplit(absl::StripAsciiWhitespace(line), ' ', absl::SkipEmpty());
    if (words.empty()) continue;
    if (words[0] == "FIELD" && !have_points) {
      return NoCounts(path, "field data before the points");
    }
    if (words[0] == "POINTS" && words.size() == 3) {
      if (!absl::SimpleAtoi(words[1], &counts.vertices) || counts.vertices < 0) break;
      have_points = true;
      if (binary) {
        const int bytes = LegacyTypeBytes(words[2]);
        if (bytes == 0) return NoCounts(path, "an unknown point type");
        in.seekg(counts.vertices * 3 * bytes, std::ios::cur);
      }
      continue;
    }
    if (words[0] == "CELLS" && words.size() == 3 && have_points) {
      int64_t cells = 0;
      if (!absl::SimpleAtoi(words[1], &cells) || cells < 0) break;
      // Version 5 files give the offsets' count (cells + 1), followed by an OFFSETS section.
      std::string next;
      std::getline(in, next);
      counts.tetrahedra =
          absl::StartsWith(next, "OFFSETS") ? std::max<int64_t>(cells - 1, 0) : cells;
      return counts;
    }
  }
  return NoCounts(path, have_points ? "no CELLS line after the points" : "no POINTS line");
}

}  // namespace

absl::StatusOr<MeshCounts> ReadMeshCounts(const std::string& path) {
  std::error_code error;
  if (!std::filesystem::is_regular_file(path, error)) {
    return absl::NotFoundError(absl::StrCat(path, ": no such file"));
  }
  const std::string extension =
      absl::AsciiStrToLower(std::filesystem::path(path).extension().string());
  if (extension == ".vtu") return UnstructuredGridCounts(path);
  if (extension == ".vti") return ImageDataCounts(path);
  if (extension == ".vtk") return LegacyCounts(path);
  if (extension == ".pvd") {
    // The first step's counts, with every step's fields.
    ASSIGN_OR_RETURN(const std::vector<CollectionStep> steps, ReadCollection(path));
    std::vector<std::string> files;
    for (const CollectionStep& step : steps) files.push_back(step.path);
    return ReadSeriesCounts(files);
  }
  return NoCounts(path, absl::StrCat("unsupported extension '", extension, "'"));
}

absl::StatusOr<MeshCounts> ReadSeriesCounts(const std::vector<std::string>& files) {
  if (files.empty()) return absl::InvalidArgumentError("a series of no files");
  ASSIGN_OR_RETURN(MeshCounts counts, ReadMeshCounts(files[0]));
  for (size_t k = 1; k < files.size(); ++k) {
    ASSIGN_OR_RETURN(const MeshCounts step, ReadMeshCounts(files[k]));
    counts.point_fields += step.point_fields;
  }
  return counts;
}

}  // namespace actopo::io
