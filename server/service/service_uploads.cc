// The upload RPCs of TopologyServiceImpl: CreateUpload, WriteUpload, GetUpload, DeleteUpload
// (upload_spool.h holds the uploads; LoadMesh with source `upload` reads one). Writing appends
// each chunk to the spool on the gRPC thread as it arrives: a file write and a hash of at most
// a message's bytes, so the client's next chunk is read meanwhile by the transport.
#include <grpcpp/grpcpp.h>

#include <optional>

#include "absl/strings/str_cat.h"
#include "server/core/status_macros.h"
#include "server/service/offload.h"
#include "server/service/service.h"
#include "server/service/wire.h"

namespace actopo::service {
namespace {

void Fill(const std::string& id, const UploadSpool::State& state, v1::UploadStatus* out) {
  out->set_upload_id(id);
  for (size_t k = 0; k < state.files.size(); ++k) {
    v1::UploadFileInfo* f = out->add_files();
    f->set_path(state.files[k].path);
    f->set_size(state.files[k].size);
    f->set_sha256(state.files[k].sha256);
    out->add_received_bytes(state.received[k]);
  }
  out->set_complete(state.complete);
  out->set_expires_in_seconds(double(state.expires_in.count()));
}

// WriteUpload: the start message, then chunks appended as they come; the upload's state at the
// end. A stream that breaks keeps what was appended: the client asks GetUpload and goes on.
class WriteUploadReactor final : public grpc::ServerReadReactor<v1::WriteUploadRequest> {
 public:
  WriteUploadReactor(ReactorHost* host, UploadSpool* spool, grpc::CallbackServerContext* context,
                     v1::WriteUploadResponse* response)
      : host_(host), spool_(spool), response_(response) {
    if (absl::Status admitted = host_->Admit(context); !admitted.ok()) {
      Done(admitted);
      return;
    }
    StartRead(&message_);
  }

  void OnReadDone(bool ok) override {
    if (!ok) {  // the client finished sending, or went away (then nobody reads the answer)
      Done(Answer());
      return;
    }
    if (absl::Status s = Consume(); !s.ok()) {
      Done(s);
      return;
    }
    StartRead(&message_);
  }

  void OnDone() override { delete this; }

 private:
  absl::Status Consume() {
    if (!writer_) {
      if (message_.payload_case() != v1::WriteUploadRequest::kStart) {
        return absl::InvalidArgumentError(
            "start: the first message of WriteUpload must say which upload, file and offset");
      }
      const v1::WriteUploadStart& start = message_.start();
      id_ = start.upload_id();
      ASSIGN_OR_RETURN(UploadSpool::Writer writer,
                       spool_->Write(start.upload_id(), start.file(), start.offset()));
      writer_.emplace(std::move(writer));
      return absl::OkStatus();
    }
    if (message_.payload_case() != v1::WriteUploadRequest::kChunk) {
      return absl::InvalidArgumentError("start: only the first message of WriteUpload is one");
    }
    return writer_->Append(message_.chunk());
  }

  absl::Status Answer() {
    if (!writer_) {
      return absl::InvalidArgumentError("start: the WriteUpload call sent nothing");
    }
    writer_.reset();  // before Get: the upload is no longer being written
    ASSIGN_OR_RETURN(const UploadSpool::State state, spool_->Get(id_));
    Fill(id_, state, response_->mutable_upload());
    return absl::OkStatus();
  }

  void Done(const absl::Status& status) {
    writer_.reset();
    host_->Count("WriteUpload", status);
    Finish(ToGrpcStatus(status));
  }

  ReactorHost* host_;
  UploadSpool* spool_;
  v1::WriteUploadResponse* response_;
  v1::WriteUploadRequest message_;
  std::string id_;
  std::optional<UploadSpool::Writer> writer_;
};

}  // namespace

grpc::ServerUnaryReactor* TopologyServiceImpl::CreateUpload(grpc::CallbackServerContext* c,
                                                            const v1::CreateUploadRequest* in,
                                                            v1::CreateUploadResponse* out) {
  return Unary(c, "CreateUpload", [&]() -> absl::Status {
    std::vector<UploadSpool::FileSpec> files;
    for (const v1::UploadFileInfo& f : in->files()) {
      files.push_back({.path = f.path(), .size = f.size(), .sha256 = f.sha256()});
    }
    ASSIGN_OR_RETURN(const std::string id, spool_->Create(std::move(files)));
    ASSIGN_OR_RETURN(const UploadSpool::State state, spool_->Get(id));
    Fill(id, state, out->mutable_upload());
    return absl::OkStatus();
  });
}

grpc::ServerReadReactor<v1::WriteUploadRequest>* TopologyServiceImpl::WriteUpload(
    grpc::CallbackServerContext* context, v1::WriteUploadResponse* response) {
  return new WriteUploadReactor(this, spool_, context, response);
}

grpc::ServerUnaryReactor* TopologyServiceImpl::GetUpload(grpc::CallbackServerContext* c,
                                                         const v1::GetUploadRequest* in,
                                                         v1::GetUploadResponse* out) {
  return Unary(c, "GetUpload", [&]() -> absl::Status {
    ASSIGN_OR_RETURN(const UploadSpool::State state, spool_->Get(in->upload_id()));
    Fill(in->upload_id(), state, out->mutable_upload());
    return absl::OkStatus();
  });
}

grpc::ServerUnaryReactor* TopologyServiceImpl::DeleteUpload(grpc::CallbackServerContext* c,
                                                            const v1::DeleteUploadRequest* in,
                                                            v1::DeleteUploadResponse*) {
  return Unary(c, "DeleteUpload", [&] { return spool_->Delete(in->upload_id()); });
}

}  // namespace actopo::service
