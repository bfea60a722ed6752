// Every request message, as arbitrary bytes parsed as its type, against a real server in this
// process (a small mesh and session loaded once). Ids left empty are filled with the real ones
// so requests get past the lookups to the validation behind them. Any status is fine; a crash,
// a sanitizer report or a hang (libFuzzer's -timeout) is a bug.
//
// Input: 1 byte choosing the RPC, then the request's protobuf bytes.
#include <grpcpp/grpcpp.h>

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <string>

#include "actopo/v1/topology_service.grpc.pb.h"
#include "server/service/server.h"

namespace {

namespace v1 = ::actopo::v1;

struct Fixture {
  std::unique_ptr<actopo::service::Server> server;
  std::unique_ptr<v1::TopologyService::Stub> stub;
  std::string mesh_id, session_id;
};

Fixture* fixture = nullptr;

std::unique_ptr<grpc::ClientContext> Context() {
  auto context = std::make_unique<grpc::ClientContext>();
  context->set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(5));
  return context;
}

// A fresh upload of one 64-byte file, for the upload requests that name none.
std::string NewUpload() {
  v1::CreateUploadRequest r;
  v1::UploadFileInfo* f = r.add_files();
  f->set_path("fuzz.vtu");
  f->set_size(64);
  f->set_sha256(std::string(64, '0'));
  v1::CreateUploadResponse out;
  (void)fixture->stub->CreateUpload(Context().get(), r, &out);
  return out.upload().upload_id();
}

void DeleteUpload(const std::string& id) {
  v1::DeleteUploadRequest r;
  r.set_upload_id(id);
  v1::DeleteUploadResponse out;
  (void)fixture->stub->DeleteUpload(Context().get(), r, &out);
}

}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  fixture = new Fixture();
  actopo::service::ServerOptions options;
  options.host = "127.0.0.1";
  options.port = 0;
  options.memory_budget_bytes = int64_t(256) << 20;  // big samples are refused, not built
  options.data_dir = std::filesystem::temp_directory_path().string();
  auto server = actopo::service::Server::Start(options);
  if (!server.ok()) std::abort();
  fixture->server = std::move(*server);
  fixture->stub = v1::TopologyService::NewStub(fixture->server->InProcessChannel());
  v1::LoadMeshRequest load;
  load.set_sample("jittered:5");
  v1::LoadMeshResponse mesh;
  if (!fixture->stub->LoadMesh(Context().get(), load, &mesh).ok()) std::abort();
  fixture->mesh_id = mesh.mesh().mesh_id();
  v1::OpenSessionRequest open;
  open.set_mesh_id(fixture->mesh_id);
  open.set_structure(v1::STRUCTURE_COMPACT);
  v1::OpenSessionResponse session;
  if (!fixture->stub->OpenSession(Context().get(), open, &session).ok()) std::abort();
  fixture->session_id = session.session().session_id();
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size < 1) return 0;
  const void* bytes = data + 1;
  const int n = int(size - 1);
  v1::TopologyService::Stub& stub = *fixture->stub;
  const auto fill = [](auto& request) {
    if (request.session_id().empty()) request.set_session_id(fixture->session_id);
  };
  switch (data[0] % 13) {
    case 0: {
      v1::GetRelationRequest r;
      if (!r.ParseFromArray(bytes, n)) return 0;
      fill(r);
      v1::GetRelationResponse out;
      (void)stub.GetRelation(Context().get(), r, &out);
      break;
    }
    case 1: {
      v1::GetRelationBatchRequest r;
      if (!r.ParseFromArray(bytes, n)) return 0;
      fill(r);
      v1::GetRelationBatchResponse out;
      (void)stub.GetRelationBatch(Context().get(), r, &out);
      break;
    }
    case 2: {
      v1::OpenSessionRequest r;
      if (!r.ParseFromArray(bytes, n)) return 0;
      if (r.mesh_id().empty()) r.set_mesh_id(fixture->mesh_id);
      v1::OpenSessionResponse out;
      if (stub.OpenSession(Context().get(), r, &out).ok()) {
        v1::CloseSessionRequest close;
        close.set_session_id(out.session().session_id());
        v1::CloseSessionResponse closed;
        (void)stub.CloseSession(Context().get(), close, &closed);
      }
      break;
    }
    case 3: {
      v1::LoadMeshRequest r;
      if (!r.ParseFromArray(bytes, n)) return 0;
      v1::LoadMeshResponse out;
      if (stub.LoadMesh(Context().get(), r, &out).ok()) {
        v1::DeleteMeshRequest del;
        del.set_mesh_id(out.mesh().mesh_id());
        v1::DeleteMeshResponse deleted;
        (void)stub.DeleteMesh(Context().get(), del, &deleted);
      }
      break;
    }
    case 4: {
      v1::RunJobRequest r;
      if (!r.ParseFromArray(bytes, n)) return 0;
      fill(r);
      auto context = Context();
      auto reader = stub.RunJob(context.get(), r);
      v1::RunJobResponse m;
      while (reader->Read(&m)) {
      }
      (void)reader->Finish();
      break;
    }
    case 5: {
      v1::StreamRelationsRequest r;
      if (!r.ParseFromArray(bytes, n)) return 0;
      fill(r);
      auto context = Context();
      auto stream = stub.StreamRelations(context.get());
      stream->Write(r);
      stream->Write(r);
      stream->WritesDone();
      v1::StreamRelationsResponse m;
      while (stream->Read(&m)) {
      }
      (void)stream->Finish();
      break;
    }
    case 6: {
      // AddFields: the header from the input, the same bytes again as the values.
      v1::AddFieldsRequest header;
      if (!header.mutable_header()->ParseFromArray(bytes, n)) return 0;
      if (header.header().mesh_id().empty()) header.mutable_header()->set_mesh_id(fixture->mesh_id);
      auto context = Context();
      v1::AddFieldsResponse out;
      auto writer = stub.AddFields(context.get(), &out);
      v1::AddFieldsRequest chunk;
      chunk.set_chunk(bytes, size_t(n));
      if (writer->Write(header)) writer->Write(chunk);
      writer->WritesDone();
      if (writer->Finish().ok()) {  // keep the fixture's mesh as it was
        for (const v1::UploadField& f : header.header().fields()) {
          v1::DeleteFieldRequest del;
          del.set_mesh_id(header.header().mesh_id());
          del.set_name(f.name());
          v1::DeleteFieldResponse deleted;
          (void)stub.DeleteField(Context().get(), del, &deleted);
        }
      }
      break;
    }
    case 7: {
      v1::DeleteFieldRequest r;
      if (!r.ParseFromArray(bytes, n)) return 0;
      if (r.mesh_id().empty()) r.set_mesh_id(fixture->mesh_id);
      if (r.name() == "scalar" || r.name() == "height") return 0;  // the session's and jobs'
      v1::DeleteFieldResponse out;
      (void)stub.DeleteField(Context().get(), r, &out);
      break;
    }
    case 9: {
      v1::DownloadMeshRequest r;
      if (!r.ParseFromArray(bytes, n)) return 0;
      if (r.mesh_id().empty()) r.set_mesh_id(fixture->mesh_id);
      auto context = Context();
      auto reader = stub.DownloadMesh(context.get(), r);
      v1::DownloadMeshResponse message;
      while (reader->Read(&message)) {
      }
      (void)reader->Finish();
      break;
    }
    case 10: {
      v1::CreateUploadRequest r;
      if (!r.ParseFromArray(bytes, n)) return 0;
      v1::CreateUploadResponse out;
      if (stub.CreateUpload(Context().get(), r, &out).ok()) DeleteUpload(out.upload().upload_id());
      break;
    }
    case 11: {
      // A start of the length the first byte says (its upload a fresh one of 64 bytes unless it
      // names one), then the rest of the input as chunks.
      if (n < 1) return 0;
      const char* in = static_cast<const char*>(bytes);
      const int length = std::min(int(uint8_t(in[0])) % 33, n - 1);
      v1::WriteUploadStart start;
      if (!start.ParseFromArray(in + 1, length)) return 0;
      const std::string fresh = NewUpload();
      if (start.upload_id().empty()) start.set_upload_id(fresh);
      auto context = Context();
      v1::WriteUploadResponse out;
      auto writer = stub.WriteUpload(context.get(), &out);
      v1::WriteUploadRequest message;
      *message.mutable_start() = start;
      writer->Write(message);
      for (int at = 1 + length; at < n; at += 16) {
        v1::WriteUploadRequest chunk;
        chunk.set_chunk(std::string(in + at, size_t(std::min(16, n - at))));
        if (!writer->Write(chunk)) break;
      }
      writer->WritesDone();
      (void)writer->Finish();
      DeleteUpload(fresh);
      break;
    }
    case 12: {
      v1::GetUploadRequest r;
      if (!r.ParseFromArray(bytes, n)) return 0;
      const std::string fresh = NewUpload();
      if (r.upload_id().empty()) r.set_upload_id(fresh);
      v1::GetUploadResponse out;
      (void)stub.GetUpload(Context().get(), r, &out);
      v1::LoadMeshRequest load;
      load.set_upload(r.upload_id());
      v1::LoadMeshResponse mesh;
      (void)stub.LoadMesh(Context().get(), load, &mesh);
      DeleteUpload(fresh);
      break;
    }
    default: {
      v1::GetSessionStatsRequest r;
      if (!r.ParseFromArray(bytes, n)) return 0;
      fill(r);
      v1::GetSessionStatsResponse out;
      (void)stub.GetSessionStats(Context().get(), r, &out);
      break;
    }
  }
  return 0;
}
