// C++ clients through Debian's HAProxy running deploy/haproxy.cfg in front of two real servers:
// every call carries the client's affinity key (x-actopo-session), so the meshes and sessions of
// a key stay on one server and every later client with that key finds them. Without haproxy
// (Debian package haproxy) the test is skipped, saying so.
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <sstream>
#include <thread>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_replace.h"
#include "tests/testing/fixture.h"

namespace actopo::client::testing {
namespace {

std::string HAProxyBinary() {
  if (const char* env = std::getenv("ACTOPO_HAPROXY_BIN")) return env;
  for (const char* path : {"/usr/sbin/haproxy", "/usr/bin/haproxy"}) {
    if (access(path, X_OK) == 0) return path;
  }
  return "";
}

int FreePort() {
  const int fd = socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in address{};
  address.sin_family = AF_INET;
  address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  socklen_t size = sizeof address;
  int port = 0;
  if (bind(fd, reinterpret_cast<sockaddr*>(&address), sizeof address) == 0 &&
      getsockname(fd, reinterpret_cast<sockaddr*>(&address), &size) == 0) {
    port = ntohs(address.sin_port);
  }
  close(fd);
  return port;
}

// deploy/haproxy.cfg with loopback addresses for its listeners and its two servers.
std::string LocalConfig(int listen, int stats, const ServerProcess& a, const ServerProcess& b) {
  std::ifstream file(ACTOPO_HAPROXY_CONFIG);
  std::stringstream text;
  text << file.rdbuf();
  return absl::StrReplaceAll(text.str(),
                             {{"bind :8080 ", absl::StrCat("bind 127.0.0.1:", listen, " ")},
                              {"bind :8404", absl::StrCat("bind 127.0.0.1:", stats)},
                              {"server-a server-a:50051", absl::StrCat("server-a ", a.target())},
                              {"server-b server-b:50051", absl::StrCat("server-b ", b.target())}});
}

std::unique_ptr<Client> Connect(const std::string& target, const std::string& key = "") {
  absl::StatusOr<std::unique_ptr<Client>> client =
      Client::Connect(target, {.retries = false, .affinity_key = key});
  EXPECT_TRUE(client.ok()) << client.status();
  return client.ok() ? *std::move(client) : nullptr;
}

TEST(AffinityTest, EveryCallOfAKeyReachesOneServerThroughHAProxy) {
  const std::string haproxy = HAProxyBinary();
  if (haproxy.empty()) {
    ACTOPO_SKIP() << "haproxy not installed (Debian package haproxy; scripts/install-deps.sh)";
  }
  absl::StatusOr<std::unique_ptr<ServerProcess>> a =
      ServerProcess::Start(ServerBinary(), DataDir());
  absl::StatusOr<std::unique_ptr<ServerProcess>> b =
      ServerProcess::Start(ServerBinary(), DataDir());
  ASSERT_OK(a);
  ASSERT_OK(b);
  const int listen = FreePort(), stats = FreePort();
  const std::string config =
      absl::StrCat(::testing::TempDir(), "/actopo_haproxy_", getpid(), ".cfg");
  std::ofstream(config) << LocalConfig(listen, stats, **a, **b);
  absl::StatusOr<std::unique_ptr<ChildProcess>> proxy =
      ChildProcess::Start({haproxy, "-q", "-f", config});
  ASSERT_OK(proxy);
  const std::string target = absl::StrCat("127.0.0.1:", listen);
  // HAProxy listens once it has read the configuration; both servers are up by then.
  bool answered = false;
  ASSERT_TRUE(WaitUntil([&] {
    answered = Connect(target, "probe")->GetServerInfo().ok();
    return answered || !(*proxy)->running();
  }));
  ASSERT_TRUE(answered) << "HAProxy did not answer on " << target << " with " << config;

  std::map<std::string, std::unique_ptr<Client>> direct;
  direct["server-a"] = Connect((*a)->target());
  direct["server-b"] = Connect((*b)->target());
  std::set<std::string> used;
  for (int i = 0; i < 8; ++i) {
    const std::string key = absl::StrCat("workflow-", i);
    std::unique_ptr<Client> client = Connect(target, key);
    absl::StatusOr<MeshInfo> mesh = client->LoadMesh("sample:jittered:6");
    ASSERT_OK(mesh) << key;
    absl::StatusOr<SessionInfo> session =
        client->OpenSession(mesh->mesh_id, {.structure = Structure::kCompact});
    ASSERT_OK(session) << key;
    // Other clients with the key reach the same server, call after call.
    for (int call = 0; call < 3; ++call) {
      std::unique_ptr<Client> again = Connect(target, key);
      EXPECT_OK(again->GetSession(session->session_id)) << key;
      EXPECT_OK(again->Relation(session->session_id, "vertex_edges", 0)) << key;
    }
    std::vector<std::string> holders;
    for (const auto& [name, server] : direct) {
      if (server->GetSession(session->session_id).ok()) holders.push_back(name);
    }
    ASSERT_EQ(holders.size(), 1u) << key;
    absl::StatusOr<SessionStats> stats = direct[holders[0]]->Stats(session->session_id);
    ASSERT_OK(stats);
    EXPECT_EQ(stats->relation_queries.count, 3) << key;
    used.insert(holders[0]);
  }
  EXPECT_EQ(used.size(), 2u) << "every key went to one server";

  // A client's own random key holds for all its calls too.
  std::unique_ptr<Client> anonymous = Connect(target);
  absl::StatusOr<MeshInfo> mesh = anonymous->LoadMesh("sample:jittered:4");
  ASSERT_OK(mesh);
  absl::StatusOr<SessionInfo> session = anonymous->OpenSession(mesh->mesh_id);
  ASSERT_OK(session);
  for (int call = 0; call < 5; ++call) EXPECT_OK(anonymous->GetSession(session->session_id));
  std::filesystem::remove(config);
}

}  // namespace
}  // namespace actopo::client::testing
