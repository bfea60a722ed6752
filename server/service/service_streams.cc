// The relation and job streams of TopologyServiceImpl: one reactor class each, whose work runs
// on the service's relations and jobs executors.
#include <grpcpp/grpcpp.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <deque>
#include <map>
#include <sstream>
#include <string>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "server/algorithms/vertex_order.h"
#include "server/core/process_memory.h"
#include "server/core/status_macros.h"
#include "server/core/sync.h"
#include "server/core/trace.h"
#include "server/results/series.h"
#include "server/service/ids.h"
#include "server/service/reactor_host.h"
#include "server/service/service.h"
#include "server/service/wire.h"

namespace actopo::service {
namespace {

constexpr size_t kChunkBytes = 1 << 20;
// A job's trace keeps its first events only, which bounds its memory and the JSON sent back.
constexpr int64_t kMaxJobTraceEvents = 250'000;

// ---------------------------------------------------------------------------------------------
// StreamRelations: errors in band. A request carries one simplex or a batch (CSR answer, with
// per-item errors). Reactions only hand over: each request read is answered on the relations
// executor, and the next one is read meanwhile, so up to kMaxAnswering answers of one stream
// compute at once (one per core of the executor) while earlier answers are written. Answers are
// written in the order of their requests: one that finishes early waits in done_ for those
// before it. Flow control: reading pauses while the answers waiting to be written hold
// kMaxQueuedBytes or kMaxQueued messages, so a client that does not read its answers holds at
// most that much server memory.
//
// Lifetime: gRPC calls OnDone once its operations are over, but answers may still be computing
// then; the reactor goes when all are done (holds_). Once Finish is called (finished_), nothing
// starts another operation: a read that completes after a failed write is dropped, and answers
// still computing are thrown away.
class StreamRelationsReactor final
    : public grpc::ServerBidiReactor<v1::StreamRelationsRequest, v1::StreamRelationsResponse> {
 public:
  StreamRelationsReactor(ReactorHost* host, grpc::CallbackServerContext* context)
      : host_(host),
        max_answering_(std::max(1, host->relations().threads())),
        deadline_(SteadyDeadline(*context)) {
    const absl::Status admitted = host_->Admit(context);
    if (!admitted.ok()) {
      host_->Count("StreamRelations", admitted);
      MutexLock lock(mu_);
      FinishLocked(ToGrpcStatus(admitted));
      return;
    }
    StartRead(&request_);
  }

  void OnReadDone(bool ok) override {
    MutexLock lock(mu_);
    if (!ok) {
      reads_done_ = true;
      MaybeFinishLocked();
      return;
    }
    if (finished_) return;  // the call already ended (a write failed): drop the request
    // Only one read is outstanding, so request_ is ours until the next StartRead.
    ++holds_;
    ++answering_;
    host_->relations().Run(cancel_,
                           [this, sequence = next_sequence_++, request = std::move(request_)] {
                             AnswerAndGo(sequence, request);
                           });
    ReadNextLocked();
  }

  void OnWriteDone(bool ok) override {
    MutexLock lock(mu_);
    queued_bytes_ -= queue_.front().bytes;
    queue_.pop_front();
    writing_ = false;
    if (!ok) {
      cancel_->store(true);
      FinishLocked(grpc::Status(grpc::StatusCode::CANCELLED, "the client went away"));
      return;
    }
    WriteNextLocked();
    if (read_paused_) ReadNextLocked();
    MaybeFinishLocked();
  }

  void OnCancel() override { cancel_->store(true); }

  void OnDone() override { Release(); }

 private:
  static constexpr size_t kMaxQueued = 256;
  static constexpr size_t kMaxQueuedBytes = size_t(32) << 20;

  struct Queued {
    v1::StreamRelationsResponse message;
    size_t bytes;
  };

  static void SetError(const absl::Status& s, v1::ItemError* error) {
    error->set_code(int(s.code()));
    error->set_message(std::string(s.message()));
  }

  // What ends an answer's wait for the mesh's faces: the call cancelled, the client gone, the
  // call's deadline.
  Progress Stop() const { return Progress({.cancel = cancel_.get(), .deadline = deadline_}); }

  v1::StreamRelationsResponse Answer(const v1::StreamRelationsRequest& request) {
    v1::StreamRelationsResponse response;
    response.set_request_id(request.request_id());
    if (host_->draining()) {
      SetError(absl::UnavailableError("the server is shutting down"), response.mutable_error());
      return response;
    }
    const int forms = request.has_simplex() + request.has_ids() + request.has_vertex_tuples();
    if (forms != 1) {
      SetError(absl::InvalidArgumentError(absl::StrCat(
                   "simplex / ids / vertex_tuples: set exactly one of them (", forms, " set)")),
               response.mutable_error());
      return response;
    }
    if (request.has_simplex()) {
      std::vector<int64_t> ids;
      const absl::Status s = host_->AnswerRelation(request.session_id(), request.relation(),
                                                   request.simplex(), false, ids, nullptr, Stop());
      if (s.ok()) {
        response.mutable_ids()->Add(ids.begin(), ids.end());
      } else {
        SetError(s, response.mutable_error());
      }
      return response;
    }
    std::vector<ReactorHost::ItemFailure> failures;
    const absl::Status s = host_->AnswerBatch(
        request.session_id(), request.relation(), request.has_ids() ? &request.ids() : nullptr,
        request.has_vertex_tuples() ? &request.vertex_tuples() : nullptr,
        response.mutable_offsets(), response.mutable_values(), &failures, Stop());
    if (!s.ok()) {
      response.clear_offsets();
      response.clear_values();
      SetError(s, response.mutable_error());
      return response;
    }
    for (const auto& [index, status] : failures) {
      v1::ItemError* error = response.add_item_errors();
      SetError(status, error);
      error->set_index(index);
    }
    return response;
  }

  // On the relations executor: answers `request`, then queues it and any answers after it that
  // were waiting for it, in request order.
  void AnswerAndGo(int64_t sequence, const v1::StreamRelationsRequest& request) {
    v1::StreamRelationsResponse response = Answer(request);
    const size_t bytes = response.ByteSizeLong();
    {
      MutexLock lock(mu_);
      --answering_;
      if (!finished_) {
        done_.emplace(sequence, Queued{std::move(response), bytes});
        for (auto next = done_.find(next_to_queue_); next != done_.end();
             next = done_.find(++next_to_queue_)) {
          queued_bytes_ += next->second.bytes;
          queue_.push_back(std::move(next->second));
          done_.erase(next);
        }
        WriteNextLocked();
        if (read_paused_) ReadNextLocked();
      }
    }
    Release();
  }

  // Reads the next request, or pauses reading while the stream's answers fill their share of
  // the executor or the queue to be written is full.
  void ReadNextLocked() ABSL_EXCLUSIVE_LOCKS_REQUIRED(mu_) {
    if (finished_) return;
    const bool room = answering_ < max_answering_ && queue_.size() + done_.size() < kMaxQueued &&
                      queued_bytes_ < kMaxQueuedBytes;
    read_paused_ = !room;
    if (room) StartRead(&request_);
  }

  void WriteNextLocked() ABSL_EXCLUSIVE_LOCKS_REQUIRED(mu_) {
    if (writing_ || finished_ || queue_.empty()) return;
    writing_ = true;
    StartWrite(&queue_.front().message);
  }

  void MaybeFinishLocked() ABSL_EXCLUSIVE_LOCKS_REQUIRED(mu_) {
    if (reads_done_ && answering_ == 0 && queue_.empty() && !writing_ && !finished_) {
      host_->Count("StreamRelations", absl::OkStatus());
      FinishLocked(grpc::Status::OK);
    }
  }

  void FinishLocked(const grpc::Status& status) ABSL_EXCLUSIVE_LOCKS_REQUIRED(mu_) {
    if (finished_) return;
    finished_ = true;
    Finish(status);
  }

  // Drops one hold (gRPC's, released by OnDone, or an answer task's); the last one deletes.
  void Release() {
    bool last;
    {
      MutexLock lock(mu_);
      last = --holds_ == 0;
      // The stream's end waits for the last answer: reads may have ended while it computed.
      if (!last) MaybeFinishLocked();
    }
    if (last) delete this;
  }

  ReactorHost* host_;
  const int max_answering_;  // answers of this stream computing at once
  const Executor::CancelFlag cancel_ = std::make_shared<std::atomic<bool>>(false);
  const Progress::Clock::time_point deadline_;  // the call's
  v1::StreamRelationsRequest request_;          // the read's target; moved into the answer task
  Mutex mu_;
  int64_t next_sequence_ ABSL_GUARDED_BY(mu_) = 0;       // of the next request read
  int64_t next_to_queue_ ABSL_GUARDED_BY(mu_) = 0;       // the answer the queue waits for
  std::map<int64_t, Queued> done_ ABSL_GUARDED_BY(mu_);  // answers ahead of their turn
  std::deque<Queued> queue_ ABSL_GUARDED_BY(mu_);        // in order; front: being written
  size_t queued_bytes_ ABSL_GUARDED_BY(mu_) = 0;
  int answering_ ABSL_GUARDED_BY(mu_) = 0;
  bool writing_ ABSL_GUARDED_BY(mu_) = false;
  bool reads_done_ ABSL_GUARDED_BY(mu_) = false;
  bool read_paused_ ABSL_GUARDED_BY(mu_) = false;
  bool finished_ ABSL_GUARDED_BY(mu_) = false;
  int holds_ ABSL_GUARDED_BY(mu_) = 1;  // gRPC's, until OnDone, and one per answer computing
};

// ---------------------------------------------------------------------------------------------
// One line on the server's stderr, written whole (one write call), so that lines of jobs ending
// together do not interleave: where each job started and how it ended, for operators and for
// the tests' failure messages.
void LogLine(const std::string& line) {
  const std::string text = absl::StrCat("actopo-server: ", line, "\n");
  std::fwrite(text.data(), 1, text.size(), stderr);
}

// RunJob: the algorithm runs on the jobs executor; its events (progress, result arrays,
// summary, statistics) are queued and written one at a time. Cancelling the call, CancelJob,
// closing the session or draining the server set the job's cancel flag; the job also stops by
// itself once the call's deadline passes (DEADLINE_EXCEEDED). The reactor goes once
// both gRPC (OnDone) and the job's task are done with it (holds_).
class RunJobReactor final : public grpc::ServerWriteReactor<v1::RunJobResponse> {
 public:
  RunJobReactor(ReactorHost* host, grpc::CallbackServerContext* context,
                const v1::RunJobRequest* request)
      : host_(host) {
    deadline_ = SteadyDeadline(*context);
    absl::Status s = host_->Admit(context);
    if (s.ok()) s = NotPastDeadline();
    if (s.ok()) s = Prepare(*request);
    if (!s.ok()) {
      host_->Count("RunJob", s);
      Finish(ToGrpcStatus(s));
      return;
    }
    v1::RunJobResponse accepted;
    accepted.mutable_accepted()->set_job_id(job_id_);
    Push(std::move(accepted));
    {
      MutexLock lock(mu_);
      ++holds_;
    }
    // The executor's cancel flag is the job's own (an aliasing pointer that keeps the job alive).
    host_->jobs().Run(Executor::CancelFlag(job_, &job_->cancel), [this] {
      host_->BeforeWork("RunJob");
      Run();
      Release();
    });
  }

  void OnWriteDone(bool ok) override {
    MutexLock lock(mu_);
    writing_ = false;
    if (!ok) {
      job_->cancel = true;
      client_gone_ = true;
    }
    WriteNextLocked();
    drained_.SignalAll();
  }

  void OnCancel() override {
    if (job_) job_->cancel = true;
  }

  void OnDone() override { Release(); }

 private:
  // Drops one hold (gRPC's, released by OnDone, or the job task's); the last one deletes.
  void Release() {
    bool last;
    {
      MutexLock lock(mu_);
      last = --holds_ == 0;
    }
    if (last) delete this;
  }

  // A call that reaches the server after its deadline (queued in gRPC while the client gave up)
  // starts no job: its client has DEADLINE_EXCEEDED already, and a job started now would hold
  // the session's lease and refuse that client's next call with FAILED_PRECONDITION.
  absl::Status NotPastDeadline() const {
    if (Progress::Clock::now() < deadline_) return absl::OkStatus();
    return absl::DeadlineExceededError("the call's deadline passed before its job started");
  }

  absl::Status Prepare(const v1::RunJobRequest& request) {
    ASSIGN_OR_RETURN(session_, host_->FindSession(request.session_id()));
    ASSIGN_OR_RETURN(input_.algorithm, FromProto(request.algorithm()));
    RETURN_IF_ERROR(SelectFields(request));
    const AlgorithmInput& base = session_->base_input();
    if (input_.algorithm == Algorithm::kMorseSmale) input_.input_corners = base.input_corners;
    std::map<std::string, std::string> parameters(request.parameters().begin(),
                                                  request.parameters().end());
    RETURN_IF_ERROR(ApplyParameters(parameters, input_));
    if (fields_.empty()) {  // the session's field; a list's fields get theirs in turn (Run)
      input_.order = base.order;
      if (NeedsScalarValues(input_)) input_.scalars = base.scalars;
    }
    RETURN_IF_ERROR(CheckMatchingEntry(input_.distance, fields_.size()));
    include_arrays_ = request.include_arrays();
    trace_ = request.trace();
    digests_ = request.digests();
    // Atomic: of N concurrent calls on a session exactly one gets the lease.
    ASSIGN_OR_RETURN(lease_, host_->StartJob(session_->id(), input_.algorithm));
    job_ = lease_.shared_job();
    job_id_ = job_->id;
    return absl::OkStatus();
  }

  // The fields a job over several runs on (RunJobRequest.fields or all_fields), held for the
  // job's length: deleting one meanwhile does not pull it from under the job.
  absl::Status SelectFields(const v1::RunJobRequest& request) {
    const Algorithm algorithm = input_.algorithm;
    const std::string name(AlgorithmName(algorithm));
    if (request.all_fields() && request.fields_size() > 0) {
      return absl::InvalidArgumentError("fields: give fields or all_fields, not both");
    }
    const FieldSet& fields = session_->mesh().fields;
    if (request.all_fields()) {
      for (const FieldSet::Ref& f : fields.List()) {
        if (f->field.is_integer) continue;
        if (absl::Status s = ValidateScalarField(f->field); !s.ok()) {
          return absl::InvalidArgumentError(absl::StrCat("all_fields: ", s.message()));
        }
        fields_.push_back(f);
      }
    }
    for (int i = 0; i < request.fields_size(); ++i) {
      const std::string& field = request.fields(i);
      for (int k = 0; k < i; ++k) {
        if (request.fields(k) == field) {
          return absl::InvalidArgumentError(
              absl::StrCat("fields[", i, "]: '", field, "' is listed twice"));
        }
      }
      absl::StatusOr<FieldSet::Ref> held =
          field.empty() ? absl::InvalidArgumentError("empty name") : fields.Select(field);
      if (!held.ok()) {
        return absl::Status(held.status().code(),
                            absl::StrCat("fields[", i, "]: ", held.status().message()));
      }
      fields_.push_back(*std::move(held));
    }
    const bool listed = request.all_fields() || request.fields_size() > 0;
    if (listed && !NeedsScalar(algorithm)) {
      return absl::InvalidArgumentError(
          absl::StrCat("fields: ", name, " reads no scalar field; run it without fields"));
    }
    if (ComparesFields(algorithm) && fields_.size() < 2) {
      return absl::InvalidArgumentError(absl::StrCat(
          "fields: ", name, " compares at least two fields; give them in fields (or all_fields)",
          listed ? absl::StrCat(", not ", fields_.size()) : std::string()));
    }
    return absl::OkStatus();
  }

  // The run's cancel flag, deadline and trace (when asked for).
  RunContext NewContext() {
    RunContext context;
    context.cancel = &job_->cancel;
    context.deadline = deadline_;
    if (trace_) {
      SetThreadRole("job");
      context.trace = std::make_shared<Trace>(kMaxJobTraceEvents);
    }
    return context;
  }

  // Progress messages: the phase, its fraction and the seconds since `start`.
  Progress::Report Reporter(std::chrono::steady_clock::time_point start) {
    return [this, start](std::string_view phase, double fraction) {
      v1::RunJobResponse progress;
      v1::JobProgress* p = progress.mutable_progress();
      p->set_phase(std::string(phase));
      p->set_fraction(fraction);
      p->set_elapsed_seconds(
          std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
      Push(std::move(progress));
    };
  }

  void Run() {
    if (!fields_.empty()) {
      RunFields();
      return;
    }
    const auto start = std::chrono::steady_clock::now();
    RunContext context = NewContext();
    const Progress::Report report = Reporter(start);
    context.progress = [report](double fraction) { report("run", fraction); };
    const std::string what = absl::StrCat(
        "job ", job_id_, " (", std::string(AlgorithmName(input_.algorithm)), ", ",
        std::string(StructureName(session_->options().structure.kind)), ", ", session_->id(), ")");
    LogLine(absl::StrCat(what, " started"));
    absl::StatusOr<JobOutcome> outcome = session_->RunJob(input_, context, report);
    lease_.Release();  // before the client can see the end of the stream
    const double seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    LogLine(absl::StrCat(what, " ended after ", absl::StrFormat("%.3f", seconds),
                         " s: ", outcome.ok() ? "OK" : outcome.status().ToString()));
    absl::Status status = outcome.status();
    if (status.ok()) status = SendResult(*outcome, context.trace.get());
    host_->Count("RunJob", status);
    if (status.ok()) {
      host_->RecordJob(AlgorithmName(input_.algorithm),
                       StructureName(session_->options().structure.kind), outcome->outcome.run_s,
                       outcome->engine);
    }
    MutexLock lock(mu_);
    final_ = ToGrpcStatus(status);
    WriteNextLocked();
  }

  absl::Status SendResult(const JobOutcome& job, Trace* trace) {
    const auto start = std::chrono::steady_clock::now();
    if (include_arrays_) {
      RETURN_IF_ERROR(SendArrays(session_->result_context(), job.outcome.result, trace));
    }
    v1::RunJobResponse summary;
    FillSummary(job.outcome.result, *session_->mesh().topology, {.digests = digests_},
                summary.mutable_summary()->mutable_result());
    if (trace != nullptr) {
      trace->Span("results", "phase", start, std::chrono::steady_clock::now());
      SendTrace(*trace);
    }
    Push(std::move(summary));
    PushStats(job.outcome.run_s, job.faces_s, job.engine, job.memory);
    return absl::OkStatus();
  }

  void PushStats(double run_s, double faces_s, const EngineStats& engine,
                 const MemoryStats& memory) {
    v1::RunJobResponse stats;
    stats.mutable_stats()->set_run_seconds(run_s);
    stats.mutable_stats()->set_faces_seconds(faces_s);
    Fill(engine, stats.mutable_stats()->mutable_engine());
    Fill(memory, stats.mutable_stats()->mutable_memory());
    stats.mutable_stats()->mutable_memory()->set_process_rss_bytes(CurrentRssBytes());
    Push(std::move(stats));
  }

  // A job over several fields: the algorithm on each field in turn, on the session's structure,
  // each field's arrays and FieldResult sent as soon as it is done; diagram-distance then
  // compares the fields' diagrams. Progress runs over the whole list, and a cancellation stops
  // the field running and the rest.
  void RunFields() {
    const auto start = std::chrono::steady_clock::now();
    RunContext context = NewContext();
    const Progress::Report report = Reporter(start);
    const std::string what = absl::StrCat(
        "job ", job_id_, " (", std::string(AlgorithmName(input_.algorithm)), " over ",
        fields_.size(), fields_.size() == 1 ? " field, " : " fields, ",
        std::string(StructureName(session_->options().structure.kind)), ", ", session_->id(), ")");
    LogLine(absl::StrCat(what, " started"));
    const absl::Status status = RunEachField(context, report);
    lease_.Release();  // before the client can see the end of the stream
    const double seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    LogLine(absl::StrCat(what, " ended after ", absl::StrFormat("%.3f", seconds),
                         " s: ", status.ToString()));
    host_->Count("RunJob", status);
    MutexLock lock(mu_);
    final_ = ToGrpcStatus(status);
    WriteNextLocked();
  }

  absl::Status RunEachField(const RunContext& context, const Progress::Report& report) {
    const LoadedMesh& mesh = session_->mesh();
    const Topology& topology = *mesh.topology;
    const size_t n = fields_.size();
    double run_s = 0, faces_s = 0;
    EngineStats engine;
    MemoryStats memory;
    std::vector<FieldDiagram> diagrams;
    nlohmann::ordered_json names = nlohmann::ordered_json::array();
    double reached = 0;  // the progress reported so far
    const auto start = std::chrono::steady_clock::now();
    for (size_t i = 0; i < n; ++i) {
      const PointField& field = fields_[i]->field;
      RETURN_IF_ERROR(context.stop().status("run"));
      AlgorithmInput input = input_;
      input.order = VertexOrder(topology, field.values);
      if (NeedsScalarValues(input)) input.scalars = field.values;
      RunContext one = context;
      // Field i fills [i / n, (i + 1) / n] of the list, never going back (an algorithm's own
      // phases may report a lower fraction than before).
      one.progress = [&report, &reached, i, n](double f) {
        reached = std::max(reached, (double(i) + f) / double(n));
        report("run", reached);
      };
      ASSIGN_OR_RETURN(JobOutcome job, session_->RunJob(input, one, report, /*whole_job=*/false));
      run_s += job.outcome.run_s;
      faces_s += job.faces_s;
      engine += job.engine;
      memory = job.memory;
      host_->RecordJob(AlgorithmName(input_.algorithm),
                       StructureName(session_->options().structure.kind), job.outcome.run_s,
                       job.engine);
      if (ComparesFields(input_.algorithm)) {
        diagrams.push_back(ToFieldDiagram(field.name,
                                          std::get<PersistenceDiagramResult>(job.outcome.result),
                                          field.values, input_.distance));
      }
      if (include_arrays_) {
        array_field_ = field.name;
        RETURN_IF_ERROR(SendArrays(
            ResultContext{mesh.mesh, topology, field.name, field.values, mesh.vertex_boundary},
            job.outcome.result, context.trace.get()));
        array_field_.clear();
      }
      v1::RunJobResponse done;
      v1::FieldResult* r = done.mutable_field();
      r->set_field(field.name);
      r->set_index(int32_t(i));
      r->set_run_seconds(job.outcome.run_s);
      FillSummary(job.outcome.result, topology, {.digests = digests_}, r->mutable_result());
      RETURN_IF_ERROR(PushPiece(std::move(done)));
      names.push_back(field.name);
    }
    nlohmann::ordered_json summary = {{"fields", names}};
    if (input_.algorithm == Algorithm::kTracking) {
      const FieldTracking tracking =
          TrackFieldDiagrams(diagrams, input_.distance, session_->options().structure.consumers);
      RETURN_IF_ERROR(context.stop().status("tracking"));
      if (include_arrays_) {
        RETURN_IF_ERROR(
            SendPolyData("tracking", TrackingPolyData(tracking, diagrams, mesh.mesh.points)));
      }
      summary = FieldTrackingJson(tracking);
    } else if (input_.algorithm == Algorithm::kDiagramDistance) {
      const Progress stop = context.stop();
      const FieldDistances distances = CompareFieldDiagrams(
          diagrams, input_.distance,
          {.threads = session_->options().structure.consumers,
           .progress = [&report](int64_t done,
                                 int64_t total) { report("distances", double(done) / total); },
           .stopped = [&stop] { return stop.stopped(); }});
      RETURN_IF_ERROR(stop.status("distances"));
      summary = FieldDistancesJson(distances);
    }
    session_->CountJob(std::chrono::duration_cast<std::chrono::nanoseconds>(
                           std::chrono::steady_clock::now() - start)
                           .count());
    v1::RunJobResponse message;
    FillStruct(summary, message.mutable_summary()->mutable_result());
    if (context.trace != nullptr) SendTrace(*context.trace);
    Push(std::move(message));
    PushStats(run_s, faces_s, engine, memory);
    return absl::OkStatus();
  }

  absl::Status SendNamed(const std::string& name, const io::NamedArray& named) {
    v1::Array header;
    const std::string_view bytes = Describe(name, named, &header);
    return SendArray(header, bytes);
  }

  absl::Status SendIds(const std::string& name, std::span<const int32_t> ids) {
    const std::vector<int64_t> wide(ids.begin(), ids.end());
    v1::Array header;
    const std::string_view bytes = Describe(name, wide, &header);
    return SendArray(header, bytes);
  }

  // Poly data as "<group>/Points", "<group>/Offsets" (and "<group>/Connectivity" when a line
  // reuses points), then its point and cell arrays.
  absl::Status SendPolyData(const std::string& group, const io::PolyData& poly) {
    v1::Array points;
    const std::string_view xyz = DescribePoints(group + "/Points", poly.points, &points);
    RETURN_IF_ERROR(SendArray(points, xyz));
    if (!poly.line_offsets.empty()) {
      RETURN_IF_ERROR(SendIds(group + "/Offsets", poly.line_offsets));
      // Lines run through consecutive points (separatrices) unless a line reuses points
      // (the diagram's diagonal): then the point ids go too.
      bool consecutive = true;
      for (size_t i = 0; i < poly.line_connectivity.size() && consecutive; ++i) {
        consecutive = poly.line_connectivity[i] == int32_t(i);
      }
      if (!consecutive) RETURN_IF_ERROR(SendIds(group + "/Connectivity", poly.line_connectivity));
    }
    for (const auto* arrays : {&poly.point_arrays, &poly.cell_arrays}) {
      for (const io::NamedArray& named : *arrays) {
        RETURN_IF_ERROR(SendNamed(group + "/" + named.name, named));
      }
    }
    return absl::OkStatus();
  }

  // A result's arrays, each in pieces (SendArray).
  absl::Status SendArrays(const ResultContext& result_context, const AlgorithmResult& result,
                          Trace* trace) {
    {
      const ResultOutputs outputs = [&] {
        Trace::Scope span(trace, "outputs", "phase");  // the arrays built, before any is sent
        return BuildOutputs(result_context, result);
      }();
      // Every array goes out in pieces straight from where it lies (SendArray).
      for (const auto& [group, poly] : outputs.poly_data) {
        RETURN_IF_ERROR(SendPolyData(group, poly));
      }
      for (const io::NamedArray& named : outputs.simplified) {
        RETURN_IF_ERROR(SendNamed("simplified/" + named.name, named));
      }
      for (const auto& [table, columns] : outputs.tables) {
        for (const io::NamedArray& named : columns) {
          RETURN_IF_ERROR(SendNamed(table + "/" + named.name, named));
        }
      }
      for (const io::NamedArray& named : outputs.segmentation) {
        RETURN_IF_ERROR(SendNamed("segmentation/" + named.name, named));
      }
    }
    return absl::OkStatus();
  }

  void SendTrace(const Trace& trace) {
    std::ostringstream out;
    trace.WriteJson(out);
    const std::string json = std::move(out).str();
    for (size_t offset = 0; offset < json.size(); offset += kChunkBytes) {
      v1::RunJobResponse message;
      v1::TraceChunk* chunk = message.mutable_trace();
      chunk->set_data(json.substr(offset, kChunkBytes));
      chunk->set_offset(int64_t(offset));
      chunk->set_total_bytes(int64_t(json.size()));
      Push(std::move(message));
    }
  }

  // Arrays go in pieces of up to kChunkBytes, each with the array's name, type and shape
  // (`header`) and its own bytes copied from `bytes`, which stay where the result keeps them:
  // with PushPiece, a result is not copied whole a second time. (Copying the whole array into
  // each piece before cutting it down would make sending quadratic in the array's size.)
  absl::Status SendArray(const v1::Array& header, std::string_view bytes) {
    size_t offset = 0;
    do {
      v1::RunJobResponse chunk;
      v1::ResultChunk* c = chunk.mutable_chunk();
      *c->mutable_array() = header;
      const size_t n = std::min(kChunkBytes, bytes.size() - offset);
      c->mutable_array()->set_data(bytes.data() + offset, n);
      c->set_offset(int64_t(offset));
      c->set_total_bytes(int64_t(bytes.size()));
      if (!array_field_.empty()) c->set_field(array_field_);
      RETURN_IF_ERROR(PushPiece(std::move(chunk)));
      offset += n;
    } while (offset < bytes.size());
    return absl::OkStatus();
  }

  // Queues a piece of the result once fewer than kMaxQueuedPieces messages wait, so a result is
  // held once while it goes out (in its outputs), not a second time in the queue: the job's
  // thread keeps pace with the client. CANCELLED once the client is gone or the call cancelled
  // (or the server drains): the rest is not sent.
  absl::Status PushPiece(v1::RunJobResponse message) {
    MutexLock lock(mu_);
    while (queue_.size() >= kMaxQueuedPieces && !client_gone_ && !job_->cancel) {
      drained_.WaitFor(mu_, std::chrono::milliseconds(100));
    }
    if (client_gone_ || job_->cancel) {
      return absl::CancelledError("job: cancelled while its result was being sent");
    }
    queue_.push_back(std::move(message));
    WriteNextLocked();
    return absl::OkStatus();
  }

  void Push(v1::RunJobResponse message) {
    MutexLock lock(mu_);
    if (client_gone_) return;
    queue_.push_back(std::move(message));
    WriteNextLocked();
  }

  // Starts the next write, or finishes once everything is written.
  void WriteNextLocked() ABSL_EXCLUSIVE_LOCKS_REQUIRED(mu_) {
    if (writing_ || finished_) return;
    if (!queue_.empty() && !client_gone_) {
      current_ = std::move(queue_.front());
      queue_.pop_front();
      writing_ = true;
      StartWrite(&current_);
      return;
    }
    if (final_) {
      finished_ = true;
      Finish(*final_);
    }
  }

  ReactorHost* host_;
  std::shared_ptr<Session> session_;
  JobLease lease_;            // released by the job's thread when the algorithm returns
  std::shared_ptr<Job> job_;  // its cancel flag, for OnCancel and OnWriteDone
  std::string job_id_;
  AlgorithmInput input_;
  std::vector<FieldSet::Ref> fields_;  // a job over several fields: each in turn
  std::string array_field_;            // the field whose arrays are being sent, in such a job
  bool include_arrays_ = false;
  bool trace_ = false;
  bool digests_ = false;
  Progress::Clock::time_point deadline_;  // the call's; the job stops by itself once it passes

  // Result pieces of up to kChunkBytes queued at most (PushPiece): 8 MiB in flight per job.
  static constexpr size_t kMaxQueuedPieces = 8;

  Mutex mu_;
  CondVar drained_;  // a write finished: PushPiece may find room
  std::deque<v1::RunJobResponse> queue_ ABSL_GUARDED_BY(mu_);
  v1::RunJobResponse current_;  // the message being written: set before StartWrite, under mu_
  bool writing_ ABSL_GUARDED_BY(mu_) = false;
  bool finished_ ABSL_GUARDED_BY(mu_) = false;
  bool client_gone_ ABSL_GUARDED_BY(mu_) = false;
  std::optional<grpc::Status> final_ ABSL_GUARDED_BY(mu_);
  int holds_ ABSL_GUARDED_BY(mu_) = 1;  // gRPC's, until OnDone, and the job task's
};

}  // namespace

grpc::ServerBidiReactor<v1::StreamRelationsRequest, v1::StreamRelationsResponse>*
TopologyServiceImpl::StreamRelations(grpc::CallbackServerContext* context) {
  return new StreamRelationsReactor(this, context);
}

grpc::ServerWriteReactor<v1::RunJobResponse>* TopologyServiceImpl::RunJob(
    grpc::CallbackServerContext* context, const v1::RunJobRequest* request) {
  return new RunJobReactor(this, context, request);
}

}  // namespace actopo::service
