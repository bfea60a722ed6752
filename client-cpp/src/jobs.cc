// Client::RunJob: the RunJob stream (accepted, progress, result chunks, summary, statistics)
// assembled into a JobResult; cancellation through a CancelToken or CancelJob.
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

// Takes one event of the stream into `result`.
absl::Status Consume(const v1::RunJobResponse& response, const JobOptions& options,
                     JobResult& result, ArrayAssembler& arrays, bool& have_summary) {
  switch (response.event_case()) {
    case v1::RunJobResponse::kAccepted:
      result.job_id = response.accepted().job_id();
      if (options.on_accepted) options.on_accepted(result.job_id);
      break;
    case v1::RunJobResponse::kProgress: {
      const v1::JobProgress& p = response.progress();
      // A server that reports no phase runs the algorithm only.
      const std::string phase = p.phase().empty() ? "run" : p.phase();
      if (options.progress && phase == "run") options.progress(p.fraction());
      if (options.phase_progress) {
        options.phase_progress(
            {.phase = phase, .fraction = p.fraction(), .elapsed_seconds = p.elapsed_seconds()});
      }
      break;
    }
    case v1::RunJobResponse::kChunk: return arrays.Add(response.chunk());
    case v1::RunJobResponse::kSummary: {
      have_summary = true;
      const auto converted = google::protobuf::util::MessageToJsonString(
          response.summary().result(), &result.summary_json);
      if (!converted.ok()) {
        return absl::DataLossError(
            absl::StrCat("summary: not convertible to JSON: ", converted.ToString()));
      }
      break;
    }
    case v1::RunJobResponse::kStats: result.stats = internal::FromProto(response.stats()); break;
    case v1::RunJobResponse::kTrace: {
      const v1::TraceChunk& piece = response.trace();
      if (result.trace.empty() && piece.total_bytes() > 0) {
        result.trace.resize(size_t(piece.total_bytes()));
      }
      const int64_t end = piece.offset() + int64_t(piece.data().size());
      if (piece.offset() < 0 || end > int64_t(result.trace.size())) {
        return absl::DataLossError(absl::StrCat("trace: bytes [", piece.offset(), ", ", end,
                                                ") outside its ", result.trace.size()));
      }
      result.trace.replace(size_t(piece.offset()), piece.data().size(), piece.data());
      break;
    }
    case v1::RunJobResponse::EVENT_NOT_SET: break;  // an event of a newer server
  }
  return absl::OkStatus();
}

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

  JobResult result;
  result.algorithm = internal::AlgorithmName(a);
  std::unique_ptr<grpc::ClientContext> context = core_->Context(options.timeout);
  grpc::ClientContext* raw = context.get();
  // Cancelling the call cancels the job on the server.
  std::shared_ptr<CancelToken::Registration> registration =
      options.cancel.OnCancel([raw] { raw->TryCancel(); });
  std::unique_ptr<grpc::ClientReader<v1::RunJobResponse>> reader =
      core_->stub->RunJob(raw, request);

  ArrayAssembler arrays;
  absl::Status problem;  // a malformed stream: the call is cancelled and this returned
  bool have_summary = false;
  v1::RunJobResponse response;
  try {
    while (problem.ok() && reader->Read(&response)) {
      problem = Consume(response, options, result, arrays, have_summary);
    }
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
  if (!have_summary) {
    return absl::DataLossError(absl::StrCat("job ", result.job_id.empty() ? "?" : result.job_id,
                                            ": the stream ended without a summary"));
  }
  ACTOPO_ASSIGN_OR_RETURN(result.arrays, arrays.Take());
  return result;
}

}  // namespace actopo::client
