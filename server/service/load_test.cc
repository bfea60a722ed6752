// Loads and session openings run in the background: progress, cancellation by the client, by the
// deadline and by draining, each leaving nothing behind (no mesh, no budget held).
#include <chrono>
#include <condition_variable>
#include <memory>
#include <mutex>
#include <string>
#include <string_view>
#include <thread>
#include <vector>

#include "server/core/testing/wait.h"
#include "server/service/testing/service_fixture.h"

namespace actopo::service {
namespace {

using testing::ServiceTest;

// A load of some weight (about 3M tetrahedra); tests that stop one midway hold it at a phase.
constexpr char kSlowSample[] = "jittered:80";

// Holds the work of one RPC at its start (ServerOptions::before_work) until opened, so a test
// can make a call's deadline pass, or other calls run, while that work has surely not ended.
class Gate {
 public:
  explicit Gate(std::string rpc) : rpc_(std::move(rpc)) {}
  void Hold(std::string_view rpc) {
    if (rpc != rpc_) return;
    std::unique_lock<std::mutex> lock(mu_);
    entered_ = true;
    changed_.notify_all();
    changed_.wait(lock, [&] { return open_; });
  }
  // Whether the held work arrived (the wait's limit only bounds a hang).
  bool WaitEntered() {
    std::unique_lock<std::mutex> lock(mu_);
    return changed_.wait_for(lock, std::chrono::seconds(60), [&] { return entered_; });
  }
  void Open() {
    std::lock_guard<std::mutex> lock(mu_);
    open_ = true;
    changed_.notify_all();
  }

 private:
  const std::string rpc_;
  std::mutex mu_;
  std::condition_variable changed_;
  bool entered_ = false, open_ = false;
};

class LoadTest : public ServiceTest {
 protected:
  void TearDown() override {
    if (gate_) gate_->Open();  // a failed test must not leave the server's work held
    ServiceTest::TearDown();
  }

  // Restarts the server with the work of `rpc` held at its start until gate_->Open().
  void HoldWorkOf(const std::string& rpc) {
    gate_ = std::make_unique<Gate>(rpc);
    options_.before_work = [gate = gate_.get()](std::string_view name) { gate->Hold(name); };
    StartServer();
  }

  // What a stopped load leaves: the server frees it after the client already has its status.
  void ExpectNothingLeftBehind() {
    actopo::testing::WaitUntil([&] { return server_->memory_budget_used_bytes() == 0; });
    EXPECT_EQ(server_->memory_budget_used_bytes(), 0);
    v1::ListMeshesResponse meshes;
    ASSERT_TRUE(stub_->ListMeshes(Context().get(), {}, &meshes).ok());
    EXPECT_EQ(meshes.meshes_size(), 0);
  }

  std::unique_ptr<Gate> gate_;

  std::unique_ptr<grpc::ClientReader<v1::LoadMeshWithProgressResponse>> StartLoad(
      grpc::ClientContext* context, const std::string& sample) {
    v1::LoadMeshWithProgressRequest request;
    request.mutable_load()->set_sample(sample);
    return stub_->LoadMeshWithProgress(context, request);
  }
};

TEST_F(LoadTest, ProgressGoesThroughThePhasesThenGivesTheMesh) {
  auto context = Context();
  auto reader = StartLoad(context.get(), "jittered:20");
  std::vector<std::string> phases;
  double last_fraction = 0, last_elapsed = 0;
  v1::LoadMeshWithProgressResponse message;
  v1::MeshInfo mesh;
  while (reader->Read(&message)) {
    ASSERT_TRUE(mesh.mesh_id().empty()) << "a message after the mesh";
    if (message.has_mesh()) {
      mesh = message.mesh();
      continue;
    }
    const v1::LoadProgress& p = message.progress();
    if (phases.empty() || phases.back() != p.phase()) {
      phases.push_back(p.phase());
      last_fraction = 0;
    }
    EXPECT_GE(p.fraction(), last_fraction) << p.phase();
    EXPECT_LE(p.fraction(), 1.0);
    EXPECT_GE(p.elapsed_seconds(), last_elapsed);
    last_fraction = p.fraction();
    last_elapsed = p.elapsed_seconds();
  }
  ASSERT_TRUE(reader->Finish().ok());
  EXPECT_EQ(phases, (std::vector<std::string>{"read", "partition", "encode"}));
  // The same mesh as a plain LoadMesh of the sample.
  v1::GetMeshRequest get;
  get.set_mesh_id(LoadSample("jittered:20", 1000));
  v1::GetMeshResponse plain;
  ASSERT_TRUE(stub_->GetMesh(Context().get(), get, &plain).ok());
  EXPECT_FALSE(mesh.mesh_id().empty());
  EXPECT_EQ(mesh.tetrahedra(), plain.mesh().tetrahedra());
  EXPECT_EQ(mesh.triangles(), plain.mesh().triangles());
  EXPECT_EQ(mesh.blocks(), plain.mesh().blocks());
}

TEST_F(LoadTest, EveryPhaseReachesTheClientOfATinyLoad) {
  // A tiny load ends while its earlier reports are still being written: the waiting reports go
  // out before the mesh, whatever the timing (a race could lose the last phase's report).
  for (int load = 0; load < 40; ++load) {
    auto context = Context();
    auto reader = StartLoad(context.get(), "jittered:3");
    std::vector<std::string> phases;
    v1::LoadMeshWithProgressResponse message;
    v1::DeleteMeshRequest del;
    while (reader->Read(&message)) {
      if (message.has_mesh()) {
        del.set_mesh_id(message.mesh().mesh_id());
      } else if (phases.empty() || phases.back() != message.progress().phase()) {
        phases.push_back(message.progress().phase());
      }
    }
    const grpc::Status status = reader->Finish();
    ASSERT_TRUE(status.ok()) << "load " << load << ": " << status.error_message();
    ASSERT_EQ(phases, (std::vector<std::string>{"read", "partition", "encode"})) << "load " << load;
    v1::DeleteMeshResponse deleted;
    ASSERT_TRUE(stub_->DeleteMesh(Context().get(), del, &deleted).ok()) << "load " << load;
  }
}

TEST_F(LoadTest, CancellingMidLoadStopsItAndFreesEverything) {
  // Cancelled as the partition begins, when the mesh is read and the most memory is held; the
  // load is held there until the cancel is in, so it cannot end first.
  HoldWorkOf("LoadMeshWithProgress/partition");
  auto context = Context();
  auto reader = StartLoad(context.get(), kSlowSample);
  ASSERT_TRUE(gate_->WaitEntered());
  context->TryCancel();
  gate_->Open();
  v1::LoadMeshWithProgressResponse message;
  bool got_mesh = false;
  while (reader->Read(&message)) got_mesh = got_mesh || message.has_mesh();
  EXPECT_EQ(reader->Finish().error_code(), grpc::StatusCode::CANCELLED);
  EXPECT_FALSE(got_mesh);
  ExpectNothingLeftBehind();
}

TEST_F(LoadTest, DeadlineStopsAPlainLoad) {
  // The load is held at its start until its deadline has passed, whatever the machine's speed.
  HoldWorkOf("LoadMesh");
  grpc::ClientContext context;
  context.set_deadline(std::chrono::system_clock::now() + std::chrono::milliseconds(100));
  v1::LoadMeshRequest request;
  request.set_sample(kSlowSample);
  v1::LoadMeshResponse response;
  EXPECT_EQ(stub_->LoadMesh(&context, request, &response).error_code(),
            grpc::StatusCode::DEADLINE_EXCEEDED);
  gate_->Open();
  ExpectNothingLeftBehind();
}

TEST_F(LoadTest, OtherCallsAreAnsweredWhileALoadRuns) {
  HoldWorkOf("LoadMeshWithProgress");
  auto context = Context();
  auto reader = StartLoad(context.get(), kSlowSample);
  ASSERT_TRUE(gate_->WaitEntered());  // the big load holds a background thread and has not ended
  // Cheap calls, and a small load and session, go through meanwhile.
  v1::GetServerInfoResponse info;
  EXPECT_TRUE(stub_->GetServerInfo(Context().get(), {}, &info).ok());
  const std::string small = LoadSample("jittered:4");
  EXPECT_FALSE(Open(small, v1::STRUCTURE_COMPACT).empty());
  v1::ListMeshesResponse meshes;
  ASSERT_TRUE(stub_->ListMeshes(Context().get(), {}, &meshes).ok());
  EXPECT_EQ(meshes.meshes_size(), 1) << "only the small mesh: the big load is held";
  gate_->Open();
  v1::LoadMeshWithProgressResponse message;
  bool got_mesh = false;
  while (reader->Read(&message)) got_mesh = message.has_mesh();
  ASSERT_TRUE(reader->Finish().ok());
  EXPECT_TRUE(got_mesh);
}

TEST_F(LoadTest, DrainingCancelsLoadsInProgress) {
  HoldWorkOf("LoadMeshWithProgress/partition");  // the load cannot end before the drain
  auto context = Context();
  auto reader = StartLoad(context.get(), kSlowSample);
  ASSERT_TRUE(gate_->WaitEntered());
  server_->Drain();
  gate_->Open();
  v1::LoadMeshWithProgressResponse message;
  bool got_mesh = false;
  while (reader->Read(&message)) got_mesh = got_mesh || message.has_mesh();
  EXPECT_EQ(reader->Finish().error_code(), grpc::StatusCode::CANCELLED);
  EXPECT_FALSE(got_mesh);
  actopo::testing::WaitUntil([&] { return server_->memory_budget_used_bytes() == 0; });
  EXPECT_EQ(server_->memory_budget_used_bytes(), 0);
}

TEST_F(LoadTest, ADeadlineStopsOpeningAnExplicitSession) {
  // The opening is held at its start until its deadline has passed, whatever the machine's speed.
  HoldWorkOf("OpenSession");
  const std::string mesh = LoadSample("jittered:60", 1000);
  const int64_t mesh_only = server_->memory_budget_used_bytes();
  grpc::ClientContext context;
  context.set_deadline(std::chrono::system_clock::now() + std::chrono::milliseconds(50));
  v1::OpenSessionRequest request;
  request.set_mesh_id(mesh);
  request.set_structure(v1::STRUCTURE_EXPLICIT);
  v1::OpenSessionResponse response;
  EXPECT_EQ(stub_->OpenSession(&context, request, &response).error_code(),
            grpc::StatusCode::DEADLINE_EXCEEDED);
  gate_->Open();
  // Once its precomputation has stopped, only the mesh is left in the budget.
  actopo::testing::WaitUntil([&] { return server_->memory_budget_used_bytes() == mesh_only; });
  EXPECT_EQ(server_->memory_budget_used_bytes(), mesh_only);
  v1::ListSessionsResponse sessions;
  ASSERT_TRUE(stub_->ListSessions(Context().get(), {}, &sessions).ok());
  EXPECT_EQ(sessions.sessions_size(), 0);
  v1::DeleteMeshRequest del;
  del.set_mesh_id(mesh);
  v1::DeleteMeshResponse deleted;
  ASSERT_TRUE(stub_->DeleteMesh(Context().get(), del, &deleted).ok());
  ExpectNothingLeftBehind();
}

}  // namespace
}  // namespace actopo::service
