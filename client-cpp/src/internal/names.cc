#include "src/internal/names.h"

#include <algorithm>
#include <cctype>
#include <utility>
#include <vector>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"

namespace actopo::client::internal {
namespace {

// (name, value) for every value of a proto enum but the _UNSPECIFIED zero, named by the value
// without `prefix`, in lower case, with `separator` between words: RELATION_VERTEX_STAR ->
// "vertex_star", ALGORITHM_MORSE_SMALE -> "morse-smale".
std::vector<std::pair<std::string, int>> EnumNames(const google::protobuf::EnumDescriptor* e,
                                                   std::string_view prefix, char separator) {
  std::vector<std::pair<std::string, int>> names;
  for (int i = 0; i < e->value_count(); ++i) {
    const google::protobuf::EnumValueDescriptor* v = e->value(i);
    if (v->number() == 0) continue;
    std::string name = v->name().substr(prefix.size());
    for (char& c : name) {
      c = c == '_' ? separator : char(std::tolower(static_cast<unsigned char>(c)));
    }
    names.emplace_back(std::move(name), v->number());
  }
  return names;
}

const std::vector<std::pair<std::string, int>>& Relations() {
  static const auto* names = new std::vector<std::pair<std::string, int>>(
      EnumNames(v1::Relation_descriptor(), "RELATION_", '_'));
  return *names;
}

const std::vector<std::pair<std::string, int>>& Algorithms() {
  static const auto* names = new std::vector<std::pair<std::string, int>>(
      EnumNames(v1::Algorithm_descriptor(), "ALGORITHM_", '-'));
  return *names;
}

// Lower case, '-' as '_', surrounding blanks dropped.
std::string Normalize(std::string_view name) {
  while (!name.empty() && std::isspace(static_cast<unsigned char>(name.front()))) {
    name.remove_prefix(1);
  }
  while (!name.empty() && std::isspace(static_cast<unsigned char>(name.back()))) {
    name.remove_suffix(1);
  }
  std::string key(name);
  for (char& c : key) c = c == '-' ? '_' : char(std::tolower(static_cast<unsigned char>(c)));
  return key;
}

absl::StatusOr<int> Lookup(const std::vector<std::pair<std::string, int>>& table,
                           std::string_view name, const std::string& what) {
  const std::string key = Normalize(name);
  for (const auto& [known, value] : table) {
    if (Normalize(known) == key) return value;
  }
  std::vector<std::string> known;
  for (const auto& entry : table) known.push_back(entry.first);
  return absl::InvalidArgumentError(absl::StrCat(what, ": unknown ", what, " '", std::string(name),
                                                 "'; available: ", absl::StrJoin(known, ", ")));
}

}  // namespace

absl::StatusOr<v1::Relation> RelationFromName(std::string_view name) {
  absl::StatusOr<int> value = Lookup(Relations(), name, "relation");
  if (!value.ok()) return value.status();
  return static_cast<v1::Relation>(*value);
}

absl::StatusOr<v1::Algorithm> AlgorithmFromName(std::string_view name) {
  absl::StatusOr<int> value = Lookup(Algorithms(), name, "algorithm");
  if (!value.ok()) return value.status();
  return static_cast<v1::Algorithm>(*value);
}

std::string AlgorithmName(v1::Algorithm algorithm) {
  for (const auto& [name, value] : Algorithms()) {
    if (value == int(algorithm)) return name;
  }
  return "";
}

v1::DataType ToProto(DataType dtype) {
  switch (dtype) {
    case DataType::kFloat32: return v1::DATA_TYPE_FLOAT32;
    case DataType::kFloat64: return v1::DATA_TYPE_FLOAT64;
    case DataType::kInt8: return v1::DATA_TYPE_INT8;
    case DataType::kInt32: return v1::DATA_TYPE_INT32;
    case DataType::kInt64: return v1::DATA_TYPE_INT64;
    case DataType::kUint8: return v1::DATA_TYPE_UINT8;
    case DataType::kUnspecified: break;
  }
  return v1::DATA_TYPE_UNSPECIFIED;
}

DataType FromProto(v1::DataType dtype) {
  switch (dtype) {
    case v1::DATA_TYPE_FLOAT32: return DataType::kFloat32;
    case v1::DATA_TYPE_FLOAT64: return DataType::kFloat64;
    case v1::DATA_TYPE_INT8: return DataType::kInt8;
    case v1::DATA_TYPE_INT32: return DataType::kInt32;
    case v1::DATA_TYPE_INT64: return DataType::kInt64;
    case v1::DATA_TYPE_UINT8: return DataType::kUint8;
    default: return DataType::kUnspecified;
  }
}

v1::Structure ToProto(Structure structure) {
  switch (structure) {
    case Structure::kExplicit: return v1::STRUCTURE_EXPLICIT;
    case Structure::kCompact: return v1::STRUCTURE_COMPACT;
    case Structure::kActopo: break;
  }
  return v1::STRUCTURE_ACTOPO;
}

Structure FromProto(v1::Structure structure) {
  switch (structure) {
    case v1::STRUCTURE_EXPLICIT: return Structure::kExplicit;
    case v1::STRUCTURE_COMPACT: return Structure::kCompact;
    default: return Structure::kActopo;  // UNSPECIFIED means actopo too
  }
}

v1::Prefetch ToProto(Prefetch prefetch) {
  switch (prefetch) {
    case Prefetch::kLinear: return v1::PREFETCH_LINEAR;
    case Prefetch::kSpatial: return v1::PREFETCH_SPATIAL;
    case Prefetch::kAdaptive: return v1::PREFETCH_ADAPTIVE;
    case Prefetch::kAuto: break;
  }
  return v1::PREFETCH_UNSPECIFIED;
}

Prefetch FromProto(v1::Prefetch prefetch) {
  switch (prefetch) {
    case v1::PREFETCH_LINEAR: return Prefetch::kLinear;
    case v1::PREFETCH_SPATIAL: return Prefetch::kSpatial;
    case v1::PREFETCH_ADAPTIVE: return Prefetch::kAdaptive;
    default: return Prefetch::kAuto;
  }
}

v1::Precompute ToProto(Precompute precompute) {
  switch (precompute) {
    case Precompute::kRequested: return v1::PRECOMPUTE_REQUESTED;
    case Precompute::kDeclared: return v1::PRECOMPUTE_DECLARED;
    case Precompute::kAuto: break;
  }
  return v1::PRECOMPUTE_UNSPECIFIED;
}

Precompute FromProto(v1::Precompute precompute) {
  switch (precompute) {
    case v1::PRECOMPUTE_REQUESTED: return Precompute::kRequested;
    case v1::PRECOMPUTE_DECLARED: return Precompute::kDeclared;
    default: return Precompute::kAuto;
  }
}

}  // namespace actopo::client::internal
