// The mesh and session RPCs of TopologyServiceImpl that take seconds on big meshes: LoadMesh,
// LoadMeshWithProgress, UploadMesh and OpenSession. Their work runs on the service's background
// executor, never on a gRPC thread, and stops when the call is cancelled, its deadline
// passes or the server drains; what it had built is freed and its budget released.
#include <grpcpp/grpcpp.h>

#include <chrono>
#include <deque>
#include <optional>
#include <thread>

#include "absl/strings/str_cat.h"
#include "server/core/process_memory.h"
#include "server/core/status_macros.h"
#include "server/core/sync.h"
#include "server/service/field_decoder.h"
#include "server/service/mesh_download.h"
#include "server/service/offload.h"
#include "server/service/service.h"
#include "server/service/upload_decoder.h"
#include "server/service/wire.h"

namespace actopo::service {
namespace {

// ---------------------------------------------------------------------------------------------
// UploadMesh: header, then raw chunks; assembled, checked against the header's counts and
// SHA-256, converted and handed to the registry. Completing (hashing, decoding, validating,
// partitioning) runs on the background executor, stopping when the call is cancelled or its
// deadline passes.
class UploadReactor final : public grpc::ServerReadReactor<v1::UploadMeshRequest> {
 public:
  UploadReactor(ReactorHost* host, grpc::CallbackServerContext* context,
                v1::UploadMeshResponse* response)
      : host_(host),
        response_(response),
        deadline_(SteadyDeadline(*context)),
        cancel_(std::make_shared<std::atomic<bool>>(false)) {
    const absl::Status admitted = host_->Admit(context);
    if (!admitted.ok()) {
      Done(admitted);
      return;
    }
    start_ = std::chrono::steady_clock::now();
    StartRead(&message_);
  }

  void OnReadDone(bool ok) override {
    if (!ok) {  // the client finished sending, or went away (then cancel_ is set)
      host_->background().Run(cancel_, [this] {
        host_->BeforeWork("UploadMesh");
        const absl::Status status =
            Complete(Progress({.cancel = cancel_.get(), .deadline = deadline_}));
        if (!status.ok()) {
          std::string().swap(data_);
          ReleaseFreeMemory();
        }
        Done(status);
      });
      return;
    }
    const absl::Status s = Consume();
    if (!s.ok()) {
      Done(s);
      return;
    }
    StartRead(&message_);
  }

  void OnCancel() override { cancel_->store(true); }
  void OnDone() override { delete this; }

 private:
  absl::Status Consume() {
    if (!have_header_) {
      if (message_.payload_case() != v1::UploadMeshRequest::kHeader) {
        return absl::InvalidArgumentError(
            "header: the first message of an upload must be the header");
      }
      header_ = message_.header();
      have_header_ = true;
      return CheckHeader();
    }
    if (message_.payload_case() != v1::UploadMeshRequest::kChunk) {
      return absl::InvalidArgumentError("chunk: only one header per upload; then send chunks");
    }
    if (data_.size() + message_.chunk().size() > expected_) {
      return absl::InvalidArgumentError(
          absl::StrCat("chunk: received more than the ", expected_, " bytes the header announced"));
    }
    data_.append(message_.chunk());
    return absl::OkStatus();
  }

  absl::Status CheckHeader() {
    ASSIGN_OR_RETURN(expected_, CheckUploadHeader(header_));
    const int64_t nv = header_.num_vertices(), nt = header_.num_tetrahedra();
    RETURN_IF_ERROR(host_->meshes().CheckCapacity());
    // Everything is reserved before a byte arrives: the raw bytes, held until the mesh is
    // decoded, and the mesh with its encodings, handed to the registry.
    const int64_t mesh_bytes = MeshRegistry::EstimateBytes(nv, nt, header_.fields_size());
    RETURN_IF_ERROR(host_->budget().Reserve(
        int64_t(expected_) + mesh_bytes,
        absl::StrCat("uploading ", nv, " vertices and ", nt, " tetrahedra (raw data and mesh)")));
    reservation_ = Reservation(&host_->budget(), int64_t(expected_));
    mesh_reservation_ = Reservation(&host_->budget(), mesh_bytes);
    data_.reserve(expected_);
    return absl::OkStatus();
  }

  absl::Status Complete(const Progress& progress) {
    if (!have_header_) return absl::InvalidArgumentError("header: the upload was empty");
    RETURN_IF_ERROR(progress.Update("read", 0));
    ASSIGN_OR_RETURN(Mesh mesh, DecodeUpload(header_, data_));
    std::string().swap(data_);
    reservation_ = Reservation();  // the raw bytes are gone
    RETURN_IF_ERROR(progress.Update("read", 1));
    const double seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
    ASSIGN_OR_RETURN(auto loaded, host_->meshes().Add(
                                      header_.name().empty() ? "upload" : header_.name(), "upload",
                                      std::move(mesh), seconds, FromProto(header_.partition()),
                                      progress, std::move(mesh_reservation_)));
    Fill(*loaded, 0, response_->mutable_mesh());
    return absl::OkStatus();
  }

  void Done(const absl::Status& status) {
    host_->Count("UploadMesh", status);
    Finish(ToGrpcStatus(status));
  }

  ReactorHost* host_;
  v1::UploadMeshResponse* response_;
  const Progress::Clock::time_point deadline_;
  const Executor::CancelFlag cancel_;
  v1::UploadMeshRequest message_;
  v1::UploadMeshHeader header_;
  bool have_header_ = false;
  size_t expected_ = 0;
  std::string data_;
  Reservation reservation_;       // the raw bytes
  Reservation mesh_reservation_;  // the mesh they make
  std::chrono::steady_clock::time_point start_;
};

// ---------------------------------------------------------------------------------------------
// AddFields: header, then raw chunks, decoded into the fields as they arrive (FieldDecoder):
// the call costs what its bytes cost. The header is checked on gRPC's thread; then a thread of
// the call's own hashes and decodes the chunks while gRPC's thread goes on receiving the next
// ones (gRPC runs reactions on the thread that reads the socket, so decoding there would stop
// the transfer), at most kQueued chunks ahead. The fields' bytes are reserved when the header
// comes, each field its own share, released with its last holder once added (FieldSet).
class AddFieldsReactor final : public grpc::ServerReadReactor<v1::AddFieldsRequest> {
 public:
  AddFieldsReactor(ReactorHost* host, grpc::CallbackServerContext* context,
                   v1::AddFieldsResponse* response)
      : host_(host), response_(response) {
    if (const absl::Status admitted = host_->Admit(context); !admitted.ok()) {
      Done(admitted);
      return;
    }
    StartRead(&message_);
  }

  void OnReadDone(bool ok) override {
    if (!started_) {  // the header: no worker yet, nothing else runs
      absl::Status s =
          ok ? Consume(message_) : absl::InvalidArgumentError("header: the call sent no header");
      if (!s.ok()) {
        Done(s);
        return;
      }
      started_ = true;
      worker_ = std::thread([this] { Work(); });
      StartRead(&message_);
      return;
    }
    MutexLock lock(mu_);
    if (finished_) return;  // a read started before the worker ended the call
    if (!ok) {
      ended_ = true;
    } else {
      queue_.push_back(std::move(message_));
      message_.Clear();
      if (queue_.size() < kQueued) {
        StartRead(&message_);
      } else {
        paused_ = true;  // the worker starts the next read when it takes a chunk
      }
    }
    arrived_.Signal();
  }

  void OnDone() override {
    if (worker_.joinable()) worker_.join();
    delete this;
  }

 private:
  static constexpr size_t kQueued = 4;  // chunks received ahead of the decoding

  // The worker: every message after the header, in order, then the fields added; it ends the
  // call, and touches nothing of the reactor once it has.
  void Work() {
    absl::Status status;
    while (true) {
      v1::AddFieldsRequest message;
      {
        MutexLock lock(mu_);
        while (queue_.empty() && !ended_) arrived_.Wait(mu_);
        if (queue_.empty()) break;  // ended: every message is decoded
        message = std::move(queue_.front());
        queue_.pop_front();
        if (paused_) {
          paused_ = false;
          StartRead(&message_);
        }
      }
      if (status = Consume(message); !status.ok()) break;
    }
    if (status.ok()) status = Complete();
    {
      MutexLock lock(mu_);
      finished_ = true;
      queue_.clear();
    }
    Done(status);
  }

  // Only the worker (or, for the header, gRPC's thread before the worker starts) decodes.
  absl::Status Consume(v1::AddFieldsRequest& message) {
    if (!decoder_) {
      if (message.payload_case() != v1::AddFieldsRequest::kHeader) {
        return absl::InvalidArgumentError(
            "header: the first message of AddFields must be the header");
      }
      return Start(message.header());
    }
    switch (message.payload_case()) {
      case v1::AddFieldsRequest::kChunk: return decoder_->Append(message.chunk());
      case v1::AddFieldsRequest::kSha256: return decoder_->SetDigest(message.sha256());
      default:
        return absl::InvalidArgumentError("chunk: only one header per call; then send chunks");
    }
  }

  absl::Status Start(const v1::AddFieldsHeader& header) {
    ASSIGN_OR_RETURN(mesh_, host_->meshes().Get(header.mesh_id()));
    ASSIGN_OR_RETURN(FieldDecoder decoder,
                     FieldDecoder::Start(header, mesh_->topology->num_vertices()));
    for (int i = 0; i < header.fields_size(); ++i) {
      const std::string& name = header.fields(i).name();
      if (mesh_->fields.Contains(name)) {  // checked again when they are added
        return absl::AlreadyExistsError(absl::StrCat("header.fields[", i, "].name: mesh '",
                                                     mesh_->id, "' has a field '", name,
                                                     "' already; delete it first"));
      }
      const int64_t bytes = int64_t(mesh_->topology->num_vertices()) * int64_t(sizeof(double));
      RETURN_IF_ERROR(host_->budget().Reserve(
          bytes, absl::StrCat("field '", name, "' of mesh '", mesh_->id, "'")));
      reservations_.emplace_back(&host_->budget(), bytes);
      if (header.fields(i).has_time()) {
        times_.emplace_back(header.fields(i).time());
      } else {
        times_.emplace_back(std::nullopt);
      }
    }
    decoder_.emplace(std::move(decoder));
    return absl::OkStatus();
  }

  absl::Status Complete() {
    ASSIGN_OR_RETURN(std::vector<PointField> decoded, decoder_->Finish());
    std::vector<FieldSet::Field> fields;
    for (size_t i = 0; i < decoded.size(); ++i) {
      fields.push_back(
          FieldSet::Make(std::move(decoded[i]), times_[i], std::move(reservations_[i])));
    }
    RETURN_IF_ERROR(mesh_->fields.Add(std::move(fields), "header.fields"));
    Fill(*mesh_, host_->SessionsOnMesh(mesh_->id), response_->mutable_mesh());
    return absl::OkStatus();
  }

  void Done(const absl::Status& status) {
    // What a refused call reserved or decoded goes before the client hears back, not when
    // gRPC deletes the reactor: its next call finds the budget as it was.
    reservations_.clear();
    decoder_.reset();
    mesh_.reset();
    host_->Count("AddFields", status);
    Finish(ToGrpcStatus(status));
  }

  ReactorHost* host_;
  v1::AddFieldsResponse* response_;
  v1::AddFieldsRequest message_;  // written by gRPC between StartRead and OnReadDone
  bool started_ = false;          // the header came; gRPC's thread's alone
  // Set by the header, then the worker's alone.
  std::shared_ptr<const LoadedMesh> mesh_;
  std::optional<FieldDecoder> decoder_;
  std::vector<Reservation> reservations_;  // one per field
  std::vector<std::optional<double>> times_;
  std::thread worker_;
  // Between gRPC's thread and the worker.
  Mutex mu_;
  CondVar arrived_;
  std::deque<v1::AddFieldsRequest> queue_ ABSL_GUARDED_BY(mu_);
  bool ended_ ABSL_GUARDED_BY(mu_) = false;     // the client sent its last message
  bool paused_ ABSL_GUARDED_BY(mu_) = false;    // no read outstanding: the queue was full
  bool finished_ ABSL_GUARDED_BY(mu_) = false;  // the worker ended the call
};

// ---------------------------------------------------------------------------------------------
// DownloadMesh: the header, then chunks of about 1 MiB made one at a time as the last one is
// written (MeshDownload), so a download holds one chunk whatever the mesh's size; a client that
// goes away stops it at its next write.
class DownloadReactor final : public grpc::ServerWriteReactor<v1::DownloadMeshResponse> {
 public:
  DownloadReactor(ReactorHost* host, grpc::CallbackServerContext* context,
                  const v1::DownloadMeshRequest* request)
      : host_(host) {
    absl::StatusOr<MeshDownload> download = Start(context, *request);
    if (!download.ok()) {
      End(download.status());
      return;
    }
    download_.emplace(*std::move(download));
    *message_.mutable_header() = download_->header();
    StartWrite(&message_);
  }

  void OnWriteDone(bool ok) override {
    if (!ok) {
      End(absl::CancelledError("the client stopped reading"));
      return;
    }
    if (!download_->Next(kChunkBytes, message_.mutable_chunk())) {
      End(absl::OkStatus());
      return;
    }
    StartWrite(&message_);
  }

  void OnDone() override { delete this; }

 private:
  static constexpr size_t kChunkBytes = size_t(1) << 20;

  absl::StatusOr<MeshDownload> Start(grpc::CallbackServerContext* context,
                                     const v1::DownloadMeshRequest& request) {
    RETURN_IF_ERROR(host_->Admit(context));
    ASSIGN_OR_RETURN(std::shared_ptr<const LoadedMesh> mesh,
                     host_->meshes().Get(request.mesh_id()));
    return MeshDownload::Start(std::move(mesh), request);
  }

  void End(const absl::Status& status) {
    download_.reset();  // the mesh is not held past the call's end
    host_->Count("DownloadMesh", status);
    Finish(ToGrpcStatus(status));
  }

  ReactorHost* host_;
  std::optional<MeshDownload> download_;
  v1::DownloadMeshResponse message_;  // ours between StartWrite and OnWriteDone
};

// ---------------------------------------------------------------------------------------------
// LoadMeshWithProgress: the load reports to this reactor from its background thread; at most one
// message is being written at a time, and a report arriving meanwhile replaces the waiting one of
// its phase, so a slow client sees fewer updates but every phase. The mesh (or the error) ends
// the stream.
class LoadProgressReactor final
    : public grpc::ServerWriteReactor<v1::LoadMeshWithProgressResponse> {
 public:
  LoadProgressReactor(ReactorHost* host, grpc::CallbackServerContext* context,
                      const v1::LoadMeshWithProgressRequest* request)
      : host_(host), start_(Progress::Clock::now()) {
    if (absl::Status admitted = host_->Admit(context); !admitted.ok()) {
      host_->Count("LoadMeshWithProgress", admitted);
      Finish(ToGrpcStatus(admitted));
      return;
    }
    const Progress::Clock::time_point deadline = SteadyDeadline(*context);
    host_->background().Run(cancel_, [this, request, deadline] {
      host_->BeforeWork("LoadMeshWithProgress");
      const Progress progress(
          {.cancel = cancel_.get(),
           .deadline = deadline,
           .report = [this](std::string_view phase, double fraction) { Report(phase, fraction); }});
      absl::StatusOr<std::shared_ptr<const LoadedMesh>> mesh =
          host_->LoadRequested(request->load(), progress);
      absl::Status status = mesh.status();
      if (!status.ok()) ReleaseFreeMemory();
      host_->Count("LoadMeshWithProgress", status);
      mu_.Lock();
      if (mesh.ok()) Fill(**mesh, 0, final_message_.mutable_mesh());
      final_ = std::move(status);
      have_final_ = true;
      if (writing_) {
        mu_.Unlock();  // OnWriteDone writes what waits, then finishes
      } else {
        FinishLocked();
      }
    });
  }

  void OnWriteDone(bool) override {
    mu_.Lock();
    writing_ = false;
    if (!waiting_.empty()) {
      WriteWaitingLocked();  // the reports made before the load ended go out before its end
    } else if (have_final_) {
      FinishLocked();
    } else {
      mu_.Unlock();
    }
  }
  void OnCancel() override { cancel_->store(true); }
  void OnDone() override { delete this; }

 private:
  // A report is sent when the phase changes, or after 1% of it or 0.2 s.
  void Report(std::string_view phase, double fraction) {
    bool phase_begins;
    {
      MutexLock lock(mu_);
      phase_begins = phase != held_phase_;
      if (phase_begins) held_phase_ = std::string(phase);
    }
    // Tests may hold the load as a phase begins (ServerOptions::before_work).
    if (phase_begins) host_->BeforeWork("LoadMeshWithProgress/" + std::string(phase));
    const auto now = Progress::Clock::now();
    mu_.Lock();
    if (phase == phase_ && fraction < 1 && fraction - sent_fraction_ < 0.01 &&
        now - sent_at_ < std::chrono::milliseconds(200)) {
      mu_.Unlock();
      return;
    }
    phase_ = std::string(phase);
    sent_fraction_ = fraction;
    sent_at_ = now;
    if (waiting_.empty() || waiting_.back().progress().phase() != phase) waiting_.emplace_back();
    v1::LoadProgress* p = waiting_.back().mutable_progress();
    p->set_phase(phase_);
    p->set_fraction(fraction);
    p->set_elapsed_seconds(std::chrono::duration<double>(now - start_).count());
    if (writing_) {
      mu_.Unlock();
    } else {
      WriteWaitingLocked();
    }
  }

  // Starts writing the oldest waiting report; releases mu_.
  void WriteWaitingLocked() ABSL_UNLOCK_FUNCTION(mu_) {
    last_.Swap(&waiting_.front());
    waiting_.pop_front();
    writing_ = true;
    mu_.Unlock();  // last_ is ours until OnWriteDone: no one else writes while writing_
    StartWrite(&last_);
  }

  // Called once, after the last write completed and none waits; releases mu_. Nothing touches
  // `this` after Finish, which may run OnDone (delete this) on another thread at once.
  void FinishLocked() ABSL_UNLOCK_FUNCTION(mu_) {
    const absl::Status status = final_;
    mu_.Unlock();
    if (status.ok()) {
      StartWriteAndFinish(&final_message_, grpc::WriteOptions(), grpc::Status::OK);
    } else {
      Finish(ToGrpcStatus(status));
    }
  }

  ReactorHost* host_;
  const Progress::Clock::time_point start_;
  const Executor::CancelFlag cancel_ = std::make_shared<std::atomic<bool>>(false);
  Mutex mu_;
  // The report being written: touched only by whoever set writing_, outside the lock.
  v1::LoadMeshWithProgressResponse last_;
  std::deque<v1::LoadMeshWithProgressResponse> waiting_ ABSL_GUARDED_BY(mu_);  // newest per phase
  v1::LoadMeshWithProgressResponse final_message_;  // the mesh: written once, before have_final_
  bool writing_ ABSL_GUARDED_BY(mu_) = false;
  bool have_final_ ABSL_GUARDED_BY(mu_) = false;
  absl::Status final_ ABSL_GUARDED_BY(mu_);
  std::string phase_ ABSL_GUARDED_BY(mu_);       // of the last report sent
  std::string held_phase_ ABSL_GUARDED_BY(mu_);  // of the last report made
  double sent_fraction_ ABSL_GUARDED_BY(mu_) = 0;
  Progress::Clock::time_point sent_at_ ABSL_GUARDED_BY(mu_);
};

}  // namespace

Progress::Clock::time_point SteadyDeadline(const grpc::CallbackServerContext& context) {
  const auto left = context.deadline() - std::chrono::system_clock::now();
  // No deadline is a time centuries away; so is anything we need not watch.
  if (left > std::chrono::hours(24 * 365)) return Progress::Clock::time_point::max();
  return Progress::Clock::now() +
         std::chrono::duration_cast<Progress::Clock::duration>(std::max(left, left.zero()));
}

absl::StatusOr<std::shared_ptr<const LoadedMesh>> TopologyServiceImpl::LoadRequested(
    const v1::LoadMeshRequest& request, const Progress& progress) {
  const PartitionOptions partition = FromProto(request.partition());
  switch (request.source_case()) {
    case v1::LoadMeshRequest::kPath: return meshes_->LoadFile(request.path(), partition, progress);
    case v1::LoadMeshRequest::kSample:
      return meshes_->LoadSample(request.sample(), partition, progress);
    case v1::LoadMeshRequest::kFiles:
      return meshes_->LoadFiles({request.files().paths().begin(), request.files().paths().end()},
                                {request.files().times().begin(), request.files().times().end()},
                                partition, progress);
    case v1::LoadMeshRequest::kUpload: {
      // The upload leaves the spool now; its folder goes when `taken` does, read or not.
      ASSIGN_OR_RETURN(const UploadSpool::Taken taken, spool_->Take(request.upload()));
      return meshes_->LoadUploaded(taken.dir(), taken.main_file(), partition, progress);
    }
    default: return absl::InvalidArgumentError("source: set path, sample, files or upload");
  }
}

grpc::ServerUnaryReactor* TopologyServiceImpl::LoadMesh(grpc::CallbackServerContext* c,
                                                        const v1::LoadMeshRequest* in,
                                                        v1::LoadMeshResponse* out) {
  return Offload(background_, c, "LoadMesh",
                 [this, in, out](const Progress& progress) -> absl::Status {
                   ASSIGN_OR_RETURN(auto mesh, LoadRequested(*in, progress));
                   Fill(*mesh, 0, out->mutable_mesh());
                   return absl::OkStatus();
                 });
}

grpc::ServerWriteReactor<v1::LoadMeshWithProgressResponse>*
TopologyServiceImpl::LoadMeshWithProgress(grpc::CallbackServerContext* context,
                                          const v1::LoadMeshWithProgressRequest* request) {
  return new LoadProgressReactor(this, context, request);
}

grpc::ServerReadReactor<v1::UploadMeshRequest>* TopologyServiceImpl::UploadMesh(
    grpc::CallbackServerContext* context, v1::UploadMeshResponse* response) {
  return new UploadReactor(this, context, response);
}

grpc::ServerWriteReactor<v1::DownloadMeshResponse>* TopologyServiceImpl::DownloadMesh(
    grpc::CallbackServerContext* context, const v1::DownloadMeshRequest* request) {
  return new DownloadReactor(this, context, request);
}

grpc::ServerReadReactor<v1::AddFieldsRequest>* TopologyServiceImpl::AddFields(
    grpc::CallbackServerContext* context, v1::AddFieldsResponse* response) {
  return new AddFieldsReactor(this, context, response);
}

grpc::ServerUnaryReactor* TopologyServiceImpl::OpenSession(grpc::CallbackServerContext* c,
                                                           const v1::OpenSessionRequest* in,
                                                           v1::OpenSessionResponse* out) {
  return Offload(background_, c, "OpenSession",
                 [this, in, out](const Progress& progress) -> absl::Status {
                   ASSIGN_OR_RETURN(auto mesh, meshes_->Get(in->mesh_id()));
                   ASSIGN_OR_RETURN(SessionOptions options, FromProto(*in));
                   ASSIGN_OR_RETURN(auto session, sessions_->Open(mesh, options, progress));
                   Fill(*session, /*running_job=*/"", out->mutable_session());
                   return absl::OkStatus();
                 });
}

}  // namespace actopo::service
