#include "tests/testing/fixture.h"

#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <map>
#include <mutex>

namespace actopo::client::testing {
namespace {

std::string EnvOr(const char* name, const char* fallback) {
  const char* value = std::getenv(name);
  return value != nullptr && *value != '\0' ? value : fallback;
}

// The server, its client and the fertility mesh, made on first use and kept until exit.
struct Shared {
  std::string skip;   // why the server tests are skipped (binary missing)
  std::string error;  // why they fail (the server would not start)
  std::unique_ptr<ServerProcess> server;
  std::unique_ptr<Client> client;
  std::string fertility;
};

Shared* shared = nullptr;  // made on first use

Shared& GetShared() {
  static std::once_flag once;
  std::call_once(once, [] {
    shared = new Shared;
    auto server = ServerProcess::Start(
        ServerBinary(), DataDir(),
        {"--max-batch-size", std::to_string(kSharedMaxBatchSize), "--max-meshes", "64"});
    if (server.status().code() == absl::StatusCode::kNotFound) {
      shared->skip = std::string(server.status().message());
      return;
    }
    if (!server.ok()) {
      shared->error = server.status().ToString();
      return;
    }
    shared->server = std::move(*server);
    auto client =
        Client::Connect(shared->server->target(), {.connect_timeout = std::chrono::seconds(30)});
    if (!client.ok()) {
      shared->error = client.status().ToString();
      return;
    }
    shared->client = std::move(*client);
  });
  return *shared;
}

// Stops the server after the last test, while main() still runs.
class StopServer : public ::testing::Environment {
 public:
  void TearDown() override {
    if (shared == nullptr) return;
    shared->client.reset();
    shared->server.reset();
  }
};
::testing::Environment* const stop_server = ::testing::AddGlobalTestEnvironment(new StopServer);

}  // namespace

std::string ServerBinary() { return EnvOr("ACTOPO_SERVER_BIN", ACTOPO_DEFAULT_SERVER_BIN); }
std::string BenchBinary() { return EnvOr("ACTOPO_BENCH_BIN", ACTOPO_DEFAULT_BENCH_BIN); }
std::string DataDir() { return EnvOr("ACTOPO_DATA_DIR", ACTOPO_DEFAULT_DATA_DIR); }

namespace {

// actopo-bench's "result" on a file under the data directory with `scalar_flags`, cached.
nlohmann::json RunBench(const std::string& file, const std::string& scalar_flags,
                        const std::string& algorithm) {
  static std::mutex mu;
  static std::map<std::string, nlohmann::json> cache;
  const std::string command = BenchBinary() + " --mesh '" + DataDir() + "/" + file + "' " +
                              scalar_flags + " --algorithm " + algorithm +
                              " --structure compact --json";
  std::lock_guard<std::mutex> lock(mu);
  if (auto it = cache.find(command); it != cache.end()) return it->second;
  FILE* pipe = popen(command.c_str(), "r");
  if (pipe == nullptr) {
    ADD_FAILURE() << "cannot run " << command;
    return nullptr;
  }
  std::string out;
  char buffer[4096];
  while (size_t n = fread(buffer, 1, sizeof buffer, pipe)) out.append(buffer, n);
  const int status = pclose(pipe);
  if (status != 0) {
    ADD_FAILURE() << command << " exited with " << status;
    return nullptr;
  }
  nlohmann::json result = nlohmann::json::parse(out, nullptr, false);
  if (result.is_discarded() || !result.contains("result")) {
    ADD_FAILURE() << command << " printed no JSON with a result: " << out;
    return nullptr;
  }
  return cache[command] = result["result"];
}

}  // namespace

nlohmann::json BenchResult(const std::string& file, const std::string& scalar,
                           const std::string& algorithm) {
  return RunBench(file, "--scalar " + scalar, algorithm);
}

nlohmann::json BenchSeriesResult(const std::string& file, const std::string& scalars,
                                 const std::string& algorithm) {
  return RunBench(file, "--scalars " + scalars, algorithm);
}

nlohmann::json TtkReference(const std::string& file, const std::string& field,
                            const std::string& section) {
  const std::string path = DataDir() + "/expected-ttk.json";
  static const nlohmann::json all = [&] {
    std::ifstream in(path);
    return nlohmann::json::parse(in, nullptr, false);
  }();
  if (all.is_discarded()) {
    ADD_FAILURE() << "cannot read " << path;
    return nullptr;
  }
  const nlohmann::json::json_pointer entry("/" + file + "/" + field + "/upstream/" + section);
  if (!all.contains(entry)) {
    ADD_FAILURE() << path << " has no " << entry.to_string();
    return nullptr;
  }
  return all[entry];
}

::testing::AssertionResult HasError(const absl::Status& status, absl::StatusCode code,
                                    const std::string& part) {
  if (status.code() != code) {
    return ::testing::AssertionFailure()
           << "expected " << absl::StatusCodeToString(code) << ", got " << status;
  }
  if (std::string(status.message()).find(part) == std::string::npos) {
    return ::testing::AssertionFailure() << "message of " << status << " lacks '" << part << "'";
  }
  return ::testing::AssertionSuccess();
}

void ServerTest::SetUp() {
  Shared& s = GetShared();
  if (!s.skip.empty()) ACTOPO_SKIP() << s.skip;
  ASSERT_TRUE(s.error.empty()) << s.error;
  client_ = s.client.get();
}

void ServerTest::TearDown() {
  if (client_ == nullptr) return;
  for (const std::string& id : sessions_) client_->CloseSession(id).IgnoreError();
  for (const std::string& id : meshes_) client_->DeleteMesh(id).IgnoreError();
}

const std::string& ServerTest::target() const { return GetShared().server->target(); }

std::unique_ptr<WorkHold> ServerTest::Hold(const std::string& work) const {
  return GetShared().server->Hold(work);
}

std::string ServerTest::Keep(const absl::StatusOr<MeshInfo>& mesh) {
  EXPECT_TRUE(mesh.ok()) << mesh.status();
  if (!mesh.ok()) return "";
  meshes_.push_back(mesh->mesh_id);
  return mesh->mesh_id;
}

std::string ServerTest::LoadSample(const std::string& name, int32_t block_size) {
  absl::StatusOr<MeshInfo> mesh = client_->LoadMesh("sample:" + name, {.block_size = block_size});
  EXPECT_TRUE(mesh.ok()) << mesh.status();
  if (!mesh.ok()) return "";
  meshes_.push_back(mesh->mesh_id);
  return mesh->mesh_id;
}

std::string ServerTest::Open(const std::string& mesh_id, const SessionOptions& options) {
  absl::StatusOr<SessionInfo> session = client_->OpenSession(mesh_id, options);
  EXPECT_TRUE(session.ok()) << session.status();
  if (!session.ok()) return "";
  sessions_.push_back(session->session_id);
  return session->session_id;
}

std::string ServerTest::Fertility() {
  Shared& s = GetShared();
  static std::mutex mu;
  std::lock_guard<std::mutex> lock(mu);
  if (s.fertility.empty()) {
    absl::StatusOr<MeshInfo> mesh = client_->LoadMesh("fertility_tet.vtu");
    EXPECT_TRUE(mesh.ok()) << mesh.status();
    if (mesh.ok()) s.fertility = mesh->mesh_id;
  }
  return s.fertility;
}

}  // namespace actopo::client::testing
