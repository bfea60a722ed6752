// A real server in the test process, a stub on its in-process channel, and helpers.
#ifndef ACTOPO_SERVER_SERVICE_TESTING_SERVICE_FIXTURE_H_
#define ACTOPO_SERVER_SERVICE_TESTING_SERVICE_FIXTURE_H_

#include <grpcpp/grpcpp.h>

#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "actopo/v1/topology_service.grpc.pb.h"
#include "gtest/gtest.h"
#include "server/io/samples.h"
#include "server/io/vtk_writer.h"
#include "server/service/server.h"

namespace actopo::service::testing {

namespace v1 = ::actopo::v1;

// A job's whole stream and how its call ended.
struct JobRun {
  grpc::Status status;
  std::vector<v1::RunJobResponse> messages;
};

inline JobRun RunJob(v1::TopologyService::Stub& stub, grpc::ClientContext* context,
                     const v1::RunJobRequest& request) {
  JobRun run;
  auto reader = stub.RunJob(context, request);
  v1::RunJobResponse message;
  while (reader->Read(&message)) run.messages.push_back(message);
  run.status = reader->Finish();
  return run;
}

class ServiceTest : public ::testing::Test {
 protected:
  // Tests may change options_ before calling StartServer(); SetUp starts a default server.
  void SetUp() override {
    data_dir_ = std::filesystem::path(::testing::TempDir()) /
                ("actopo_service_" + std::to_string(::getpid()) + "_" +
                 ::testing::UnitTest::GetInstance()->current_test_info()->name());
    std::filesystem::create_directories(data_dir_ / "sub");
    // A small file under the data directory, and one beside it that must stay unreachable.
    const Mesh mesh = *io::MakeSample("jittered:6");
    ASSERT_TRUE(io::WriteUnstructuredGrid((data_dir_ / "sub" / "cube.vtu").string(), mesh).ok());
    options_.port = 0;
    options_.host = "127.0.0.1";
    options_.data_dir = data_dir_.string();
    options_.mesh_reader = ACTOPO_READER_BIN;  // files are read in a child, as by actopo-server
    options_.memory_budget_bytes = int64_t(4) << 30;
    StartServer();
  }

  void TearDown() override {
    stub_.reset();
    if (server_) server_->Shutdown(absl::Seconds(2));
    server_.reset();
    std::filesystem::remove_all(data_dir_);
  }

  void StartServer() {
    stub_.reset();
    if (server_) server_->Shutdown(absl::Seconds(1));
    auto server = Server::Start(options_);
    ASSERT_TRUE(server.ok()) << server.status();
    server_ = std::move(*server);
    stub_ = v1::TopologyService::NewStub(server_->InProcessChannel());
  }

  std::unique_ptr<grpc::ClientContext> Context() {
    auto c = std::make_unique<grpc::ClientContext>();
    c->set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(60));
    if (!token_.empty()) c->AddMetadata("authorization", "Bearer " + token_);
    return c;
  }

  std::string LoadSample(const std::string& sample, int block_size = 50) {
    v1::LoadMeshRequest request;
    request.set_sample(sample);
    request.mutable_partition()->set_block_size(block_size);
    v1::LoadMeshResponse response;
    const grpc::Status s = stub_->LoadMesh(Context().get(), request, &response);
    EXPECT_TRUE(s.ok()) << s.error_message();
    return response.mesh().mesh_id();
  }

  std::string Open(const std::string& mesh_id, v1::Structure structure, int consumers = 1,
                   int producers = 2) {
    v1::OpenSessionRequest request;
    request.set_mesh_id(mesh_id);
    request.set_structure(structure);
    request.mutable_engine()->set_consumers(consumers);
    request.mutable_engine()->set_producers(producers);
    v1::OpenSessionResponse response;
    const grpc::Status s = stub_->OpenSession(Context().get(), request, &response);
    EXPECT_TRUE(s.ok()) << s.error_message();
    return response.session().session_id();
  }

  ServerOptions options_;
  std::filesystem::path data_dir_;
  std::string token_;
  std::unique_ptr<Server> server_;
  std::unique_ptr<v1::TopologyService::Stub> stub_;
};

}  // namespace actopo::service::testing

#endif  // ACTOPO_SERVER_SERVICE_TESTING_SERVICE_FIXTURE_H_
