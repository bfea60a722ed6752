// Jobs over several fields: a result's field by name, and the summaries of diagram-distance and
// tracking jobs read into DistanceMatrix and TrackingSummary (Client::DiagramDistances runs the
// first). The summary is JSON text in the JobResult; it is read back through protobuf's Struct,
// the form it travelled in.
#include <algorithm>
#include <cmath>
#include <limits>

#include "absl/strings/str_cat.h"
#include "actopo/client.h"
#include "google/protobuf/struct.pb.h"
#include "google/protobuf/util/json_util.h"
#include "src/internal/core.h"

namespace actopo::client {
namespace {

using google::protobuf::Struct;
using google::protobuf::Value;

// Reads the keys of one algorithm's summary; errors name the algorithm and the key.
class SummaryReader {
 public:
  // NOT_FOUND unless `result` is a job of `algorithm`; DATA_LOSS if its summary is no object.
  static absl::StatusOr<SummaryReader> Open(const JobResult& result, std::string_view algorithm) {
    if (result.algorithm != algorithm) {
      return absl::NotFoundError(absl::StrCat("job ", result.job_id, " ran ", result.algorithm,
                                              ": only a ", std::string(algorithm),
                                              " job's summary has this"));
    }
    SummaryReader reader(algorithm);
    const auto parsed =
        google::protobuf::util::JsonStringToMessage(result.summary_json, &reader.summary_);
    if (!parsed.ok()) {
      return absl::DataLossError(absl::StrCat(
          std::string(algorithm), " summary: not a JSON object (", parsed.ToString(), ")"));
    }
    return reader;
  }

  absl::StatusOr<double> Number(std::string_view key) const {
    ACTOPO_ASSIGN_OR_RETURN(const Value* value, Get(key));
    return ToNumber(*value, key);
  }

  absl::StatusOr<int64_t> Integer(std::string_view key) const {
    ACTOPO_ASSIGN_OR_RETURN(const Value* value, Get(key));
    return ToInteger(*value, key);
  }

  absl::StatusOr<bool> Boolean(std::string_view key) const {
    ACTOPO_ASSIGN_OR_RETURN(const Value* value, Get(key));
    if (value->kind_case() != Value::kBoolValue) return Bad(key, "not true or false");
    return value->bool_value();
  }

  absl::StatusOr<std::vector<std::string>> Strings(std::string_view key) const {
    ACTOPO_ASSIGN_OR_RETURN(const Value* value, Get(key));
    if (value->kind_case() != Value::kListValue) return Bad(key, "not a list");
    std::vector<std::string> out;
    for (const Value& v : value->list_value().values()) {
      if (v.kind_case() != Value::kStringValue) return Bad(key, "not a list of strings");
      out.push_back(v.string_value());
    }
    return out;
  }

  // A list of numbers; with `length` >= 0, exactly that many.
  absl::StatusOr<std::vector<double>> Numbers(std::string_view key, int64_t length = -1) const {
    ACTOPO_ASSIGN_OR_RETURN(const Value* value, Get(key));
    return ToNumbers(*value, key, length);
  }

  absl::StatusOr<std::vector<int64_t>> Integers(std::string_view key, int64_t length = -1) const {
    ACTOPO_ASSIGN_OR_RETURN(const Value* value, Get(key));
    if (value->kind_case() != Value::kListValue) return Bad(key, "not a list");
    std::vector<int64_t> out;
    for (const Value& v : value->list_value().values()) {
      ACTOPO_ASSIGN_OR_RETURN(out.emplace_back(), ToInteger(v, key));
    }
    if (length >= 0 && int64_t(out.size()) != length) {
      return Bad(key, absl::StrCat(out.size(), " entries, expected ", length));
    }
    return out;
  }

  // A list of `rows` lists of `columns` numbers each.
  absl::StatusOr<std::vector<std::vector<double>>> Rows(std::string_view key, int64_t rows,
                                                        int64_t columns) const {
    ACTOPO_ASSIGN_OR_RETURN(const Value* value, Get(key));
    if (value->kind_case() != Value::kListValue || value->list_value().values_size() != rows) {
      return Bad(key, absl::StrCat("not a list of ", rows, " rows"));
    }
    std::vector<std::vector<double>> out;
    for (const Value& row : value->list_value().values()) {
      ACTOPO_ASSIGN_OR_RETURN(out.emplace_back(), ToNumbers(row, key, columns));
    }
    return out;
  }

 private:
  explicit SummaryReader(std::string_view algorithm) : algorithm_(algorithm) {}

  absl::Status Bad(std::string_view key, std::string_view what) const {
    return absl::DataLossError(
        absl::StrCat(algorithm_, " summary: '", std::string(key), "': ", std::string(what)));
  }

  absl::StatusOr<const Value*> Get(std::string_view key) const {
    const auto it = summary_.fields().find(std::string(key));
    if (it == summary_.fields().end()) return Bad(key, "missing");
    return &it->second;
  }

  // JSON has no infinity: protobuf, which wrote summary_json, spells an infinite distance
  // "Infinity", and actopo-bench (nlohmann::json) null.
  absl::StatusOr<double> ToNumber(const Value& v, std::string_view key) const {
    constexpr double kInfinity = std::numeric_limits<double>::infinity();
    switch (v.kind_case()) {
      case Value::kNumberValue: return v.number_value();
      case Value::kNullValue: return kInfinity;
      case Value::kStringValue:
        if (v.string_value() == "Infinity") return kInfinity;
        if (v.string_value() == "-Infinity") return -kInfinity;
        break;
      default: break;
    }
    return Bad(key, "not a number");
  }

  absl::StatusOr<int64_t> ToInteger(const Value& v, std::string_view key) const {
    if (v.kind_case() != Value::kNumberValue || v.number_value() != std::trunc(v.number_value()) ||
        std::abs(v.number_value()) > 9.0e15) {
      return Bad(key, "not an integer");
    }
    return int64_t(v.number_value());
  }

  absl::StatusOr<std::vector<double>> ToNumbers(const Value& v, std::string_view key,
                                                int64_t length) const {
    if (v.kind_case() != Value::kListValue) return Bad(key, "not a list");
    std::vector<double> out;
    for (const Value& item : v.list_value().values()) {
      ACTOPO_ASSIGN_OR_RETURN(out.emplace_back(), ToNumber(item, key));
    }
    if (length >= 0 && int64_t(out.size()) != length) {
      return Bad(key, absl::StrCat(out.size(), " entries, expected ", length));
    }
    return out;
  }

  std::string algorithm_;
  Struct summary_;
};

}  // namespace

const FieldResult* JobResult::Field(std::string_view name) const {
  for (const FieldResult& f : fields) {
    if (f.field == name) return &f;
  }
  return nullptr;
}

absl::StatusOr<DistanceMatrix> JobResult::Distances() const {
  ACTOPO_ASSIGN_OR_RETURN(const SummaryReader summary,
                          SummaryReader::Open(*this, "diagram-distance"));
  DistanceMatrix out;
  ACTOPO_ASSIGN_OR_RETURN(out.fields, summary.Strings("fields"));
  const int64_t n = int64_t(out.fields.size());
  ACTOPO_ASSIGN_OR_RETURN(out.p, summary.Number("p"));
  ACTOPO_ASSIGN_OR_RETURN(out.essential, summary.Boolean("essential"));
  for (auto [key, matrix] :
       {std::pair{"wasserstein", &out.wasserstein}, std::pair{"bottleneck", &out.bottleneck}}) {
    ACTOPO_ASSIGN_OR_RETURN(const std::vector<std::vector<double>> rows, summary.Rows(key, n, n));
    matrix->reserve(size_t(n * n));
    for (const std::vector<double>& row : rows) {
      matrix->insert(matrix->end(), row.begin(), row.end());
    }
  }
  ACTOPO_ASSIGN_OR_RETURN(out.pairs, summary.Integers("pairs", n));
  ACTOPO_ASSIGN_OR_RETURN(out.thresholds, summary.Numbers("thresholds", n));
  ACTOPO_ASSIGN_OR_RETURN(out.distance_seconds, summary.Number("distance_seconds"));
  return out;
}

absl::StatusOr<TrackingSummary> JobResult::Tracking() const {
  ACTOPO_ASSIGN_OR_RETURN(const SummaryReader summary, SummaryReader::Open(*this, "tracking"));
  TrackingSummary out;
  ACTOPO_ASSIGN_OR_RETURN(out.fields, summary.Strings("fields"));
  const int64_t steps = std::max<int64_t>(int64_t(out.fields.size()) - 1, 0);
  ACTOPO_ASSIGN_OR_RETURN(out.p, summary.Number("p"));
  ACTOPO_ASSIGN_OR_RETURN(out.trajectories, summary.Integer("trajectories"));
  ACTOPO_ASSIGN_OR_RETURN(out.trajectories_by_type, summary.Integers("trajectories_by_type"));
  ACTOPO_ASSIGN_OR_RETURN(out.links, summary.Integer("links"));
  ACTOPO_ASSIGN_OR_RETURN(out.longest, summary.Integer("longest"));
  ACTOPO_ASSIGN_OR_RETURN(out.step_wasserstein, summary.Numbers("step_wasserstein", steps));
  ACTOPO_ASSIGN_OR_RETURN(
      out.step_wasserstein_by_type,
      summary.Rows("step_wasserstein_by_type", steps, int64_t(out.trajectories_by_type.size())));
  ACTOPO_ASSIGN_OR_RETURN(out.tracking_seconds, summary.Number("tracking_seconds"));
  return out;
}

absl::StatusOr<DistanceMatrix> Client::DiagramDistances(
    std::string_view session_id, const std::map<std::string, std::string>& parameters,
    const JobOptions& options) {
  JobOptions job = options;
  job.include_arrays = false;  // the diagrams are not needed for the matrix
  if (job.fields.empty()) job.all_fields = true;
  ACTOPO_ASSIGN_OR_RETURN(const JobResult result,
                          RunJob(session_id, "diagram-distance", parameters, job));
  return result.Distances();
}

}  // namespace actopo::client
