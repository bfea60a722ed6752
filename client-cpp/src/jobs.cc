// Client::RunJob: the RunJob stream (accepted, progress, result chunks, each field's result in a
// job over fields, summary, statistics) assembled into a JobResult; cancellation through a
// CancelToken or CancelJob.
#include <cstring>

#include "absl/strings/str_cat.h"
#include "actopo/client.h"
#include "google/protobuf/util/json_util.h"
#include "src/internal/convert.h"
#include "src/internal/core.h"
#include "src/internal/names.h"

namespace actopo::client {
namespace {

// Result arrays arrive in pieces (ResultChunk: offset and total bytes of the whole array).
class ArrayAssembler {
 public:
  absl::Status Add(const v1::ResultChunk& chunk) {
    const v1::Array& piece = chunk.array();
    auto [it, inserted] = arrays_.try_emplace(piece.name());
    Array& array = it->second;
    if (inserted) {
      if (chunk.total_bytes() < 0) return Bad(piece.name(), "a negative total size");
      array.name = piece.name();
      array.dtype = internal::FromProto(piece.dtype());
      array.shape.assign(piece.shape().begin(), piece.shape().end());
      array.data.resize(size_t(chunk.total_bytes()));
    }
    const int64_t end = chunk.offset() + int64_t(piece.data().size());
    if (chunk.offset() < 0 || end > int64_t(array.data.size())) {
      return Bad(piece.name(), absl::StrCat("bytes [", chunk.offset(), ", ", end, ") outside its ",
                                            array.data.size()));
    }
    if (!piece.data().empty()) {
      std::memcpy(array.data.data() + chunk.offset(), piece.data().data(), piece.data().size());
    }
    received_[piece.name()] += int64_t(piece.data().size());
    return absl::OkStatus();
  }

  // The arrays, once every byte of each arrived.
  absl::StatusOr<std::map<std::string, Array, std::less<>>> Take() {
    for (const auto& [name, array] : arrays_) {
      if (received_[name] != int64_t(array.data.size())) {
        return Bad(name,
                   absl::StrCat(received_[name], " of ", array.data.size(), " bytes received"));
      }
    }
    return std::move(arrays_);
  }

 private:
  static absl::Status Bad(const std::string& name, const std::string& what) {
    return absl::DataLossError(absl::StrCat("result array '", name, "': ", what));
  }

  std::map<std::string, Array, std::less<>> arrays_;
  std::map<std::string, int64_t> received_;
};

// A summary (google.protobuf.Struct) as JSON text.
absl::Status ToJson(const google::protobuf::Struct& summary, std::string_view what,
                    std::string* out) {
  const auto converted = google::protobuf::util::MessageToJsonString(summary, out);
  if (!converted.ok()) {
    return absl::DataLossError(
        absl::StrCat(std::string(what), ": not convertible to JSON: ", converted.ToString()));
  }
  return absl::OkStatus();
}

// The stream of a RunJob call taken into a JobResult, event by event.
class JobStream {
 public:
  JobStream(const JobOptions& options, JobResult& result) : options_(options), result_(result) {}

  absl::Status Consume(const v1::RunJobResponse& response) {
    switch (response.event_case()) {
      case v1::RunJobResponse::kAccepted:
        result_.job_id = response.accepted().job_id();
        if (options_.on_accepted) options_.on_accepted(result_.job_id);
        break;
      case v1::RunJobResponse::kProgress: {
        const v1::JobProgress& p = response.progress();
        // A server that reports no phase runs the algorithm only.
        const std::string phase = p.phase().empty() ? "run" : p.phase();
        if (options_.progress && phase == "run") options_.progress(p.fraction());
        if (options_.phase_progress) {
          options_.phase_progress(
              {.phase = phase, .fraction = p.fraction(), .elapsed_seconds = p.elapsed_seconds()});
        }
        break;
      }
      case v1::RunJobResponse::kChunk: {
        // In a job over fields a field's arrays are its own until its FieldResult comes.
        const std::string& field = response.chunk().field();
        return (field.empty() ? arrays_ : field_arrays_[field]).Add(response.chunk());
      }
      case v1::RunJobResponse::kField: return TakeField(response.field());
      case v1::RunJobResponse::kSummary:
        have_summary_ = true;
        return ToJson(response.summary().result(), "summary", &result_.summary_json);
      case v1::RunJobResponse::kStats: result_.stats = internal::FromProto(response.stats()); break;
      case v1::RunJobResponse::kTrace: {
        const v1::TraceChunk& piece = response.trace();
        std::string& trace = result_.trace;
        if (trace.empty() && piece.total_bytes() > 0) trace.resize(size_t(piece.total_bytes()));
        const int64_t end = piece.offset() + int64_t(piece.data().size());
        if (piece.offset() < 0 || end > int64_t(trace.size())) {
          return absl::DataLossError(absl::StrCat("trace: bytes [", piece.offset(), ", ", end,
                                                  ") outside its ", trace.size()));
        }
        trace.replace(size_t(piece.offset()), piece.data().size(), piece.data());
        break;
      }
      case v1::RunJobResponse::EVENT_NOT_SET: break;  // an event of a newer server
    }
    return absl::OkStatus();
  }

  // After the stream ended well: the summary came, and every array is whole and claimed.
  absl::Status Finish() {
    if (!have_summary_) {
      return absl::DataLossError(absl::StrCat("job ", result_.job_id.empty() ? "?" : result_.job_id,
                                              ": the stream ended without a summary"));
    }
    if (!field_arrays_.empty()) {
      return absl::DataLossError(absl::StrCat("result arrays of field '",
                                              field_arrays_.begin()->first,
                                              "': the stream ended without the field's result"));
    }
    ACTOPO_ASSIGN_OR_RETURN(result_.arrays, arrays_.Take());
    return absl::OkStatus();
  }

 private:
  absl::Status TakeField(const v1::FieldResult& message) {
    FieldResult field;
    field.field = message.field();
    field.index = message.index();
    field.run_seconds = message.run_seconds();
    ACTOPO_RETURN_IF_ERROR(ToJson(message.result(),
                                  absl::StrCat("result of field '", message.field(), "'"),
                                  &field.summary_json));
    if (auto it = field_arrays_.find(message.field()); it != field_arrays_.end()) {
      ACTOPO_ASSIGN_OR_RETURN(field.arrays, it->second.Take());
      field_arrays_.erase(it);
    }
    if (options_.on_field) options_.on_field(field);
    if (options_.keep_fields) result_.fields.push_back(std::move(field));
    return absl::OkStatus();
  }

  const JobOptions& options_;
  JobResult& result_;
  ArrayAssembler arrays_;                               // the job's own
  std::map<std::string, ArrayAssembler> field_arrays_;  // by field, until its FieldResult
  bool have_summary_ = false;
};

}  // namespace

absl::StatusOr<JobResult> Client::RunJob(std::string_view session_id, std::string_view algorithm,
                                         const std::map<std::string, std::string>& parameters,
                                         const JobOptions& options) {
  ACTOPO_ASSIGN_OR_RETURN(v1::Algorithm a, internal::AlgorithmFromName(algorithm));
  if (options.cancel.cancelled()) {
    return absl::CancelledError("job: cancelled before it started");
  }
  v1::RunJobRequest request;
  request.set_session_id(std::string(session_id));
  request.set_algorithm(a);
  request.mutable_parameters()->insert(parameters.begin(), parameters.end());
  request.set_include_arrays(options.include_arrays);
  request.set_trace(options.trace);
  request.set_digests(options.digests);
  if (options.all_fields && !options.fields.empty()) {
    return absl::InvalidArgumentError(
        "options.fields, options.all_fields: give fields or all_fields, not both");
  }
  request.mutable_fields()->Add(options.fields.begin(), options.fields.end());
  request.set_all_fields(options.all_fields);

  JobResult result;
  result.algorithm = internal::AlgorithmName(a);
  std::unique_ptr<grpc::ClientContext> context = core_->Context(options.timeout);
  grpc::ClientContext* raw = context.get();
  // Cancelling the call cancels the job on the server.
  std::shared_ptr<CancelToken::Registration> registration =
      options.cancel.OnCancel([raw] { raw->TryCancel(); });
  std::unique_ptr<grpc::ClientReader<v1::RunJobResponse>> reader =
      core_->stub->RunJob(raw, request);

  JobStream stream(options, result);
  absl::Status problem;  // a malformed stream: the call is cancelled and this returned
  v1::RunJobResponse response;
  try {
    while (problem.ok() && reader->Read(&response)) problem = stream.Consume(response);
  } catch (...) {  // from a callback: end the call (and the job) before the stack unwinds
    raw->TryCancel();
    while (reader->Read(&response)) {
    }
    reader->Finish();
    throw;
  }
  if (!problem.ok()) {
    raw->TryCancel();
    while (reader->Read(&response)) {
    }
  }
  const grpc::Status status = reader->Finish();
  registration.reset();  // before the context goes
  ACTOPO_RETURN_IF_ERROR(problem);
  ACTOPO_RETURN_IF_ERROR(internal::FromGrpc(status));
  ACTOPO_RETURN_IF_ERROR(stream.Finish());
  return result;
}

}  // namespace actopo::client
