// Uploads of mesh files as their bytes (Client::UploadFile and the calls under it): a shared .vtu
// and a .pvd with two files load as from the server's data directory; an upload goes on after a
// WriteUpload stream cancelled mid-way and after a connection cut by a proxy, and one that gives
// up is kept for a later call; the bad inputs (a wrong SHA-256, more bytes than announced, a
// file that is not a mesh or that changes while sent, a .pvd naming files outside its folder, an
// upload over the server's budget) each get their status, and the upload is gone after them.
#include <grpcpp/grpcpp.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <mutex>
#include <optional>
#include <sstream>
#include <thread>
#include <vector>

#include "absl/strings/str_cat.h"
#include "actopo/v1/topology_service.grpc.pb.h"
#include "tests/testing/fixture.h"

namespace actopo::client::testing {
namespace {

namespace fs = std::filesystem;
using absl::StatusCode;

std::string ReadFile(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

void WriteFile(const fs::path& path, const std::string& bytes) {
  fs::create_directories(path.parent_path());
  std::ofstream(path, std::ios::binary) << bytes;
}

// A fresh folder, removed with everything in it when the object goes.
class TempDir {
 public:
  TempDir() {
    std::string name = (fs::temp_directory_path() / "actopo_upload_XXXXXX").string();
    if (mkdtemp(name.data()) != nullptr) path_ = name;
  }
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;
  ~TempDir() {
    std::error_code ec;
    if (!path_.empty()) fs::remove_all(path_, ec);
  }
  const fs::path& path() const { return path_; }

 private:
  fs::path path_;
};

// A TCP proxy on a loopback port in front of a server. On the first connection it stops
// reading from the client once `stall_after` bytes came from it (what it forwarded reaches the
// server, nothing more), until Cut() closes that connection both ways. Later connections pass
// everything, or with `refuse_after_cut` are closed as soon as they are accepted (a server gone
// for good).
class CuttingProxy {
 public:
  CuttingProxy(int upstream_port, int64_t stall_after, bool refuse_after_cut = false)
      : upstream_port_(upstream_port), stall_after_(stall_after), refuse_(refuse_after_cut) {
    listen_ = socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
    sockaddr_in address = Loopback(0);
    socklen_t size = sizeof address;
    if (bind(listen_, reinterpret_cast<sockaddr*>(&address), sizeof address) == 0 &&
        listen(listen_, 16) == 0 &&
        getsockname(listen_, reinterpret_cast<sockaddr*>(&address), &size) == 0) {
      port_ = ntohs(address.sin_port);
    }
    acceptor_ = std::thread([this] { Accept(); });
  }
  CuttingProxy(const CuttingProxy&) = delete;
  CuttingProxy& operator=(const CuttingProxy&) = delete;
  ~CuttingProxy() {
    shutdown(listen_, SHUT_RDWR);  // accept() returns
    acceptor_.join();
    {
      std::lock_guard<std::mutex> lock(mu_);
      for (int fd : sockets_) shutdown(fd, SHUT_RDWR);  // every pump's poll() returns
    }
    for (std::thread& t : pumps_) t.join();
    for (int fd : sockets_) close(fd);
    close(listen_);
  }

  std::string target() const { return absl::StrCat("127.0.0.1:", port_); }
  bool ok() const { return port_ > 0; }
  // Closes the first connection, both ways.
  void Cut() {
    std::lock_guard<std::mutex> lock(mu_);
    if (sockets_.size() >= 2) {
      shutdown(sockets_[0], SHUT_RDWR);
      shutdown(sockets_[1], SHUT_RDWR);
    }
    cut_ = true;
  }
  bool cut() const { return cut_; }
  // Whether the first connection has stopped reading from the client.
  bool stalled() const { return stalled_; }
  int connections() const { return connections_; }

 private:
  static sockaddr_in Loopback(int port) {
    sockaddr_in address{};
    address.sin_family = AF_INET;
    address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    address.sin_port = htons(uint16_t(port));
    return address;
  }

  void Accept() {
    while (true) {
      const int client = accept4(listen_, nullptr, nullptr, SOCK_CLOEXEC);
      if (client < 0) return;  // shut down
      const int server = socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
      const sockaddr_in address = Loopback(upstream_port_);
      std::lock_guard<std::mutex> lock(mu_);
      sockets_.push_back(client);
      sockets_.push_back(server);
      const bool first = connections_++ == 0;
      if ((!first && refuse_ && cut_) ||
          connect(server, reinterpret_cast<const sockaddr*>(&address), sizeof address) != 0) {
        shutdown(client, SHUT_RDWR);
        continue;
      }
      pumps_.emplace_back([this, client, server, first] { Pump(client, server, first); });
    }
  }

  // Copies bytes both ways until either side closes; the sockets are closed by the destructor
  // only, so that it never shuts down a number reused meanwhile.
  void Pump(int client, int server, bool first) {
    int64_t up = 0;
    char buffer[16384];
    pollfd fds[2] = {{.fd = client, .events = POLLIN, .revents = 0},
                     {.fd = server, .events = POLLIN, .revents = 0}};
    while (poll(fds, 2, -1) > 0) {
      for (int side = 0; side < 2; ++side) {
        if (fds[side].fd < 0 || fds[side].revents == 0) continue;
        const int to = side == 0 ? server : client;
        size_t want = sizeof buffer;
        if (first && side == 0) want = size_t(std::min<int64_t>(int64_t(want), stall_after_ - up));
        const ssize_t n = read(fds[side].fd, buffer, want);
        if (n <= 0) {
          shutdown(client, SHUT_RDWR);
          shutdown(server, SHUT_RDWR);
          return;
        }
        for (ssize_t done = 0; done < n;) {
          const ssize_t w = send(to, buffer + done, size_t(n - done), MSG_NOSIGNAL);
          if (w <= 0) return;
          done += w;
        }
        if (side == 0) up += n;
        if (first && up >= stall_after_) {
          fds[0].fd = -1;  // poll() leaves it alone
          stalled_ = true;
        }
      }
    }
  }

  const int upstream_port_;
  const int64_t stall_after_;
  const bool refuse_;
  int listen_ = -1;
  int port_ = 0;
  std::atomic<bool> cut_{false};
  std::atomic<bool> stalled_{false};
  std::atomic<int> connections_{0};
  std::mutex mu_;
  std::vector<int> sockets_;  // client, server, client, server, ...: guarded by mu_
  std::vector<std::thread> pumps_;
  std::thread acceptor_;
};

// Cuts `proxy`'s first connection once the server (asked by `direct`) holds some bytes of the
// upload whose id `id` gets (under `mu`), from another thread while UploadFile runs.
class CutOnceHeld {
 public:
  CutOnceHeld(CuttingProxy& proxy, Client& direct, std::mutex& mu, const std::string& id)
      : thread_([&proxy, &direct, &mu, &id, this] {
          held_ = WaitUntil([&] {
            std::string known;
            {
              std::lock_guard<std::mutex> lock(mu);
              known = id;
            }
            if (known.empty()) return false;
            absl::StatusOr<UploadStatus> upload = direct.GetUpload(known);
            return upload.ok() && !upload->received_bytes.empty() && upload->received_bytes[0] > 0;
          });
          proxy.Cut();  // also when the wait failed: UploadFile must end
        }) {}
  CutOnceHeld(const CutOnceHeld&) = delete;
  CutOnceHeld& operator=(const CutOnceHeld&) = delete;
  ~CutOnceHeld() { Join(); }
  // Whether the server held bytes when the connection was cut.
  bool Join() {
    if (thread_.joinable()) thread_.join();
    return held_;
  }

 private:
  std::atomic<bool> held_{false};
  std::thread thread_;
};

// Every report of an upload, and what the test asks of them.
struct Reports {
  std::vector<UploadFileProgress> all;

  std::function<void(const UploadFileProgress&)> Recorder() {
    return [this](const UploadFileProgress& p) { all.push_back(p); };
  }
  // The phases in the order they came, each once per run of reports.
  std::vector<std::string> Phases() const {
    std::vector<std::string> phases;
    for (const UploadFileProgress& p : all) {
      if (phases.empty() || phases.back() != p.phase) phases.push_back(p.phase);
    }
    return phases;
  }
  std::vector<UploadFileProgress> Of(const std::string& phase) const {
    std::vector<UploadFileProgress> out;
    for (const UploadFileProgress& p : all) {
      if (p.phase == phase) out.push_back(p);
    }
    return out;
  }
};

class UploadFileTest : public ServerTest {
 protected:
  static std::string Data(const std::string& file) { return DataDir() + "/" + file; }
  int Port() const { return std::stoi(target().substr(target().rfind(':') + 1)); }

  // Expects `mesh` to be fertility_tet.vtu as LoadMesh reads it from the data directory.
  void ExpectFertility(const absl::StatusOr<MeshInfo>& mesh) {
    ASSERT_OK(mesh);
    absl::StatusOr<MeshInfo> loaded = client().GetMesh(Fertility());
    ASSERT_OK(loaded);
    EXPECT_EQ(mesh->name, "fertility_tet.vtu");
    EXPECT_EQ(mesh->source, "upload:fertility_tet.vtu");
    EXPECT_EQ(mesh->vertices, loaded->vertices);
    EXPECT_EQ(mesh->tetrahedra, loaded->tetrahedra);
    ASSERT_EQ(mesh->fields.size(), loaded->fields.size());
    for (size_t i = 0; i < mesh->fields.size(); ++i) {
      EXPECT_EQ(mesh->fields[i].name, loaded->fields[i].name);
      EXPECT_EQ(mesh->fields[i].dtype, loaded->fields[i].dtype);
      EXPECT_EQ(mesh->fields[i].min, loaded->fields[i].min);
      EXPECT_EQ(mesh->fields[i].max, loaded->fields[i].max);
    }
  }
};

// ---------------------------------------------------------------------------------------------
// Round trips.

TEST_F(UploadFileTest, SharedVtuLoadsAsFromTheDataDirectory) {
  const std::string path = Data("fertility_tet.vtu");
  const int64_t size = int64_t(fs::file_size(path));
  Reports reports;
  absl::StatusOr<MeshInfo> mesh =
      client().UploadFile(path, {.progress = reports.Recorder(), .chunk_bytes = 256 << 10});
  const std::string id = Keep(mesh);
  ASSERT_FALSE(id.empty());
  ExpectFertility(mesh);

  // Hashing, sending, then the load's own phases.
  const std::vector<std::string> phases = reports.Phases();
  ASSERT_GE(phases.size(), 3u);
  EXPECT_EQ(phases[0], "hash");
  EXPECT_EQ(phases[1], "send");
  EXPECT_EQ(phases[2], "read");
  const std::vector<UploadFileProgress> sent = reports.Of("send");
  ASSERT_GE(sent.size(), 6u);  // the start, then one per chunk of 256 KiB
  EXPECT_EQ(sent.front().bytes, 0);
  for (size_t i = 1; i < sent.size(); ++i) EXPECT_GT(sent[i].bytes, sent[i - 1].bytes);
  EXPECT_EQ(sent.back().bytes, size);
  EXPECT_EQ(sent.back().total_bytes, size);
  EXPECT_EQ(sent.back().sent_bytes, size);
  EXPECT_DOUBLE_EQ(sent.back().fraction, 1.0);
  EXPECT_EQ(sent.back().resumes, 0);
  EXPECT_FALSE(sent.back().upload_id.empty());
  EXPECT_EQ(reports.Of("hash").back().bytes, size);
  // The load dropped the upload.
  EXPECT_TRUE(HasError(client().GetUpload(sent.back().upload_id), StatusCode::kNotFound));

  // The same critical points as on the mesh loaded from the data directory.
  const std::string uploaded = Open(id, {.scalar = "eigenfunction4"});
  const std::string loaded = Open(Fertility(), {.scalar = "eigenfunction4"});
  absl::StatusOr<JobResult> a = client().RunJob(uploaded, "critical-points");
  absl::StatusOr<JobResult> b = client().RunJob(loaded, "critical-points");
  ASSERT_OK(a);
  ASSERT_OK(b);
  EXPECT_EQ(nlohmann::json::parse(a->summary_json)["counts"],
            nlohmann::json::parse(b->summary_json)["counts"]);
  EXPECT_EQ(a->Get<int8_t>("critical_points/CriticalType").value(),
            b->Get<int8_t>("critical_points/CriticalType").value());
}

TEST_F(UploadFileTest, PvdWithTwoFilesLoadsAsASeries) {
  TempDir dir;
  ASSERT_FALSE(dir.path().empty());
  const std::string series = Data("isabel_series_s2");
  fs::create_directories(dir.path() / "steps");
  fs::copy_file(series + "/isabel_02_s2_tet.vtu", dir.path() / "steps/isabel_02_s2_tet.vtu");
  fs::copy_file(series + "/isabel_03_s2_tet.vtu", dir.path() / "isabel_03_s2_tet.vtu");
  // A file in a subfolder, one named with "./", and a comment that is no DataSet.
  WriteFile(dir.path() / "series.pvd",
            "<?xml version=\"1.0\"?>\n"
            "<VTKFile type=\"Collection\" version=\"0.1\">\n"
            "  <!-- <DataSet file=\"../elsewhere.vtu\"/> -->\n"
            "  <Collection>\n"
            "    <DataSet timestep=\"2\" part=\"0\" file=\"steps/isabel_02_s2_tet.vtu\"/>\n"
            "    <DataSet timestep='3' part='0' file='./isabel_03_s2_tet.vtu' />\n"
            "  </Collection>\n"
            "</VTKFile>\n");
  Reports reports;
  absl::StatusOr<MeshInfo> mesh =
      client().UploadFile((dir.path() / "series.pvd").string(), {.progress = reports.Recorder()});
  ASSERT_FALSE(Keep(mesh).empty());
  EXPECT_EQ(mesh->name, "series.pvd");
  EXPECT_EQ(mesh->source, "upload:series.pvd");
  EXPECT_EQ(reports.Of("send").back().total_bytes,
            int64_t(fs::file_size(dir.path() / "series.pvd") +
                    fs::file_size(series + "/isabel_02_s2_tet.vtu") +
                    fs::file_size(series + "/isabel_03_s2_tet.vtu")));

  const std::string loaded = Keep(client().LoadSeries(
      {"isabel_series_s2/isabel_02_s2_tet.vtu", "isabel_series_s2/isabel_03_s2_tet.vtu"},
      {2.0, 3.0}));
  absl::StatusOr<MeshInfo> expected = client().GetMesh(loaded);
  ASSERT_OK(expected);
  EXPECT_EQ(mesh->vertices, expected->vertices);
  EXPECT_EQ(mesh->tetrahedra, expected->tetrahedra);
  ASSERT_EQ(mesh->fields.size(), 2u);
  ASSERT_EQ(expected->fields.size(), 2u);
  for (size_t i = 0; i < 2; ++i) {
    EXPECT_EQ(mesh->fields[i].name, absl::StrCat("velocityMag_", i));
    EXPECT_EQ(mesh->fields[i].name, expected->fields[i].name);
    EXPECT_EQ(mesh->fields[i].min, expected->fields[i].min);
    EXPECT_EQ(mesh->fields[i].max, expected->fields[i].max);
    EXPECT_EQ(mesh->fields[i].time, std::optional<double>(2.0 + double(i)));
  }
}

// ---------------------------------------------------------------------------------------------
// Going on after a broken stream.

TEST_F(UploadFileTest, GoesOnAfterACancelledStream) {
  const std::string path = Data("fertility_tet.vtu");
  const std::string bytes = ReadFile(path);
  const int64_t size = int64_t(bytes.size());
  absl::StatusOr<std::string> sha256 = FileSha256(path);
  ASSERT_OK(sha256);
  absl::StatusOr<UploadStatus> created =
      client().CreateUpload({{.path = "fertility_tet.vtu", .size = size, .sha256 = *sha256}});
  ASSERT_OK(created);
  const std::string id = created->upload_id;
  EXPECT_EQ(created->received_bytes, std::vector<int64_t>{0});
  EXPECT_FALSE(created->complete);
  EXPECT_GT(created->expires_in_seconds, 0);

  // A raw WriteUpload stream sends part of the file, then is cancelled.
  constexpr int64_t kPart = 400'000;
  auto stub = v1::TopologyService::NewStub(
      grpc::CreateChannel(target(), grpc::InsecureChannelCredentials()));
  grpc::ClientContext context;
  v1::WriteUploadResponse response;
  std::unique_ptr<grpc::ClientWriter<v1::WriteUploadRequest>> writer =
      stub->WriteUpload(&context, &response);
  v1::WriteUploadRequest message;
  message.mutable_start()->set_upload_id(id);
  ASSERT_TRUE(writer->Write(message));
  for (int64_t at = 0; at < kPart; at += 100'000) {
    message.set_chunk(bytes.substr(size_t(at), 100'000));
    ASSERT_TRUE(writer->Write(message));
  }
  ASSERT_TRUE(WaitUntil([&] {
    absl::StatusOr<UploadStatus> held = client().GetUpload(id);
    return held.ok() && held->received_bytes == std::vector<int64_t>{kPart};
  }));
  context.TryCancel();
  EXPECT_EQ(writer->Finish().error_code(), grpc::StatusCode::CANCELLED);
  // The server keeps what the broken stream appended.
  absl::StatusOr<UploadStatus> held = client().GetUpload(id);
  ASSERT_OK(held);
  EXPECT_EQ(held->received_bytes, std::vector<int64_t>{kPart});
  EXPECT_FALSE(held->complete);

  // UploadFile goes on from there and sends the rest only: were the cancelled stream still
  // held on the server, its stream of no bytes would wait for it before any chunk is sent.
  Reports reports;
  absl::StatusOr<MeshInfo> mesh = client().UploadFile(
      path, {.progress = reports.Recorder(), .chunk_bytes = 64 << 10, .upload_id = id});
  ASSERT_FALSE(Keep(mesh).empty());
  ExpectFertility(mesh);
  const std::vector<UploadFileProgress> sent = reports.Of("send");
  ASSERT_FALSE(sent.empty());
  EXPECT_EQ(sent.front().bytes, kPart);
  EXPECT_EQ(sent.front().upload_id, id);
  EXPECT_EQ(sent.back().bytes, size);
  EXPECT_EQ(sent.back().sent_bytes, size - kPart);
  EXPECT_TRUE(HasError(client().GetUpload(id), StatusCode::kNotFound, id));
}

TEST_F(UploadFileTest, GoesOnAfterACutConnection) {
  CuttingProxy proxy(Port(), /*stall_after=*/600 << 10);
  ASSERT_TRUE(proxy.ok());
  absl::StatusOr<std::unique_ptr<Client>> proxied = Client::Connect(proxy.target());
  ASSERT_OK(proxied);
  const std::string path = Data("fertility_tet.vtu");
  const int64_t size = int64_t(fs::file_size(path));
  std::mutex mu;
  std::string id;
  Reports reports;
  const auto record = reports.Recorder();
  CutOnceHeld cutter(proxy, client(), mu, id);
  absl::StatusOr<MeshInfo> mesh =
      (*proxied)->UploadFile(path, {.progress =
                                        [&](const UploadFileProgress& p) {
                                          std::lock_guard<std::mutex> lock(mu);
                                          id = p.upload_id;
                                          record(p);
                                        },
                                    .chunk_bytes = 64 << 10});
  EXPECT_TRUE(cutter.Join());
  ASSERT_FALSE(Keep(mesh).empty());
  ExpectFertility(mesh);
  EXPECT_TRUE(proxy.cut());
  EXPECT_GE(proxy.connections(), 2);
  // After the cut it went on from the bytes the server held, and sent only the rest.
  std::optional<UploadFileProgress> resumed;
  for (const UploadFileProgress& p : reports.Of("send")) {
    if (p.resumes > 0) {
      resumed = p;
      break;
    }
  }
  ASSERT_TRUE(resumed.has_value());
  EXPECT_GT(resumed->bytes, 0);
  const UploadFileProgress& last = reports.Of("send").back();
  EXPECT_EQ(last.bytes, size);
  EXPECT_EQ(last.sent_bytes - resumed->sent_bytes, size - resumed->bytes);
}

TEST_F(UploadFileTest, GivesUpKeepingTheUploadForALaterCall) {
  // The server is reachable through the proxy until the cut, never after.
  CuttingProxy proxy(Port(), /*stall_after=*/600 << 10, /*refuse_after_cut=*/true);
  ASSERT_TRUE(proxy.ok());
  absl::StatusOr<std::unique_ptr<Client>> proxied =
      Client::Connect(proxy.target(), {.retries = false});
  ASSERT_OK(proxied);
  const std::string path = Data("fertility_tet.vtu");
  const int64_t size = int64_t(fs::file_size(path));
  std::mutex mu;
  std::string id;
  CutOnceHeld cutter(proxy, client(), mu, id);
  absl::StatusOr<MeshInfo> gave_up =
      (*proxied)->UploadFile(path, {.progress =
                                        [&](const UploadFileProgress& p) {
                                          std::lock_guard<std::mutex> lock(mu);
                                          id = p.upload_id;
                                        },
                                    .chunk_bytes = 64 << 10,
                                    .max_resumes = 2});
  EXPECT_TRUE(cutter.Join());
  EXPECT_TRUE(HasError(gave_up, StatusCode::kUnavailable, "gave up after 2 resumptions"));
  ASSERT_FALSE(id.empty());
  EXPECT_TRUE(HasError(gave_up, StatusCode::kUnavailable, id));

  // The server kept it, with what arrived before the cut; another client goes on with it.
  absl::StatusOr<UploadStatus> held = client().GetUpload(id);
  ASSERT_OK(held);
  ASSERT_EQ(held->received_bytes.size(), 1u);
  EXPECT_GT(held->received_bytes[0], 0);
  EXPECT_LT(held->received_bytes[0], size);
  Reports reports;
  absl::StatusOr<MeshInfo> mesh =
      client().UploadFile(path, {.progress = reports.Recorder(), .upload_id = id});
  ASSERT_FALSE(Keep(mesh).empty());
  ExpectFertility(mesh);
  EXPECT_EQ(reports.Of("send").back().sent_bytes, size - held->received_bytes[0]);
}

// ---------------------------------------------------------------------------------------------
// Bad input: each with its status, and the upload gone after it.

TEST_F(UploadFileTest, WrongSha256IsDataLoss) {
  const std::string bytes = ReadFile(Data("manifoldCheck0_tet.vtu"));
  absl::StatusOr<std::string> other = FileSha256(Data("manifoldCheck1_tet.vtu"));
  ASSERT_OK(other);
  absl::StatusOr<UploadStatus> upload = client().CreateUpload(
      {{.path = "manifoldCheck0_tet.vtu", .size = int64_t(bytes.size()), .sha256 = *other}});
  ASSERT_OK(upload);
  EXPECT_TRUE(HasError(client().WriteUpload(upload->upload_id, 0, 0,
                                            std::as_bytes(std::span(bytes)), /*chunk_bytes=*/500),
                       StatusCode::kDataLoss,
                       "'manifoldCheck0_tet.vtu': the bytes received hash to"));
  EXPECT_TRUE(
      HasError(client().GetUpload(upload->upload_id), StatusCode::kNotFound, upload->upload_id));
}

TEST_F(UploadFileTest, WritesMustFollowWhatTheServerHolds) {
  const std::string path = Data("manifoldCheck0_tet.vtu");
  const std::string bytes = ReadFile(path);
  absl::StatusOr<std::string> sha256 = FileSha256(path);
  ASSERT_OK(sha256);
  const UploadFileInfo file{.path = "m.vtu", .size = int64_t(bytes.size()), .sha256 = *sha256};
  absl::StatusOr<UploadStatus> upload = client().CreateUpload({file});
  ASSERT_OK(upload);
  const std::string& id = upload->upload_id;
  const auto span = std::as_bytes(std::span(bytes));
  // An offset other than what the server holds, an incomplete upload loaded, another file's
  // upload to go on with: refused, the upload kept.
  EXPECT_TRUE(HasError(client().WriteUpload(id, 0, 5, span), StatusCode::kFailedPrecondition,
                       "the server holds 0 bytes"));
  absl::StatusOr<UploadStatus> half = client().WriteUpload(id, 0, 0, span.first(1000));
  ASSERT_OK(half);
  EXPECT_EQ(half->received_bytes, std::vector<int64_t>{1000});
  EXPECT_TRUE(
      HasError(client().LoadUpload(id), StatusCode::kFailedPrecondition, "send the rest first"));
  EXPECT_TRUE(HasError(client().UploadFile(Data("manifoldCheck1_tet.vtu"), {.upload_id = id}),
                       StatusCode::kFailedPrecondition, "options.upload_id"));
  // More bytes than announced: refused, the upload dropped.
  std::string more = bytes.substr(1000) + "x";
  EXPECT_TRUE(HasError(client().WriteUpload(id, 0, 1000, std::as_bytes(std::span(more))),
                       StatusCode::kInvalidArgument, "more than the"));
  EXPECT_TRUE(HasError(client().GetUpload(id), StatusCode::kNotFound));

  // DeleteUpload drops one at once.
  absl::StatusOr<UploadStatus> again = client().CreateUpload({file});
  ASSERT_OK(again);
  EXPECT_OK(client().DeleteUpload(again->upload_id));
  EXPECT_TRUE(HasError(client().GetUpload(again->upload_id), StatusCode::kNotFound));
  EXPECT_TRUE(HasError(client().DeleteUpload(again->upload_id), StatusCode::kNotFound));
}

TEST_F(UploadFileTest, NotAMeshIsTheLoadsErrorNamingTheFile) {
  TempDir dir;
  ASSERT_FALSE(dir.path().empty());
  WriteFile(dir.path() / "notes.vtu", "these are notes, not a mesh\n");
  std::string id;
  absl::StatusOr<MeshInfo> mesh =
      client().UploadFile((dir.path() / "notes.vtu").string(),
                          {.progress = [&](const UploadFileProgress& p) { id = p.upload_id; }});
  EXPECT_TRUE(HasError(mesh, StatusCode::kInvalidArgument, "notes.vtu"));
  ASSERT_FALSE(id.empty());
  EXPECT_TRUE(HasError(client().GetUpload(id), StatusCode::kNotFound));
}

TEST_F(UploadFileTest, FileChangedWhileSentIsAborted) {
  TempDir dir;
  ASSERT_FALSE(dir.path().empty());
  const fs::path path = dir.path() / "fertility_tet.vtu";
  fs::copy_file(Data("fertility_tet.vtu"), path);
  std::string id;
  absl::StatusOr<MeshInfo> mesh = client().UploadFile(
      path.string(), {.progress =
                          [&](const UploadFileProgress& p) {
                            if (p.phase == "send" && p.sent_bytes > 0 && id.empty()) {
                              id = p.upload_id;
                              fs::resize_file(path, 100'000);  // after the first chunk
                            }
                          },
                      .chunk_bytes = 64 << 10});
  EXPECT_TRUE(HasError(mesh, StatusCode::kAborted, "changed while being uploaded"));
  EXPECT_TRUE(HasError(mesh, StatusCode::kAborted, path.string()));
  ASSERT_FALSE(id.empty());
  EXPECT_TRUE(HasError(client().GetUpload(id), StatusCode::kNotFound));
}

TEST_F(UploadFileTest, CancelledUploadIsDropped) {
  CancelToken cancel;
  std::string id;
  absl::StatusOr<MeshInfo> mesh = client().UploadFile(
      Data("fertility_tet.vtu"), {.progress =
                                      [&](const UploadFileProgress& p) {
                                        if (p.phase == "send" && p.sent_bytes > 0) {
                                          id = p.upload_id;
                                          cancel.Cancel();
                                        }
                                      },
                                  .chunk_bytes = 64 << 10,
                                  .cancel = cancel});
  EXPECT_TRUE(HasError(mesh, StatusCode::kCancelled));
  ASSERT_FALSE(id.empty());
  EXPECT_TRUE(HasError(client().GetUpload(id), StatusCode::kNotFound));
}

// Cancelled once the link carries nothing more (the proxy stalls the connection): the upload is
// still deleted, as its DeleteUpload goes on a connection of its own. On the client's connection
// it would wait behind the cancelled stream's bytes until its deadline.
TEST_F(UploadFileTest, CancelledUploadIsDroppedPastAStalledConnection) {
  CuttingProxy proxy(Port(), /*stall_after=*/300 << 10);
  ASSERT_TRUE(proxy.ok());
  absl::StatusOr<std::unique_ptr<Client>> proxied =
      Client::Connect(proxy.target(), {.default_timeout = std::chrono::seconds(5)});
  ASSERT_OK(proxied);
  CancelToken cancel;
  std::string id;
  std::thread canceller([&] {
    WaitUntil([&] { return proxy.stalled(); });
    cancel.Cancel();  // also when the wait failed: UploadFile must end
  });
  absl::StatusOr<MeshInfo> mesh =
      (*proxied)->UploadFile(Data("fertility_tet.vtu"), {.progress =
                                                             [&](const UploadFileProgress& p) {
                                                               if (!p.upload_id.empty())
                                                                 id = p.upload_id;
                                                             },
                                                         .chunk_bytes = 64 << 10,
                                                         .cancel = cancel});
  canceller.join();
  EXPECT_TRUE(proxy.stalled());
  EXPECT_TRUE(HasError(mesh, StatusCode::kCancelled));
  ASSERT_FALSE(id.empty());
  EXPECT_TRUE(HasError(client().GetUpload(id), StatusCode::kNotFound));
  EXPECT_GE(proxy.connections(), 2);
}

TEST_F(UploadFileTest, OverTheUploadBudgetIsResourceExhausted) {
  absl::StatusOr<std::unique_ptr<ServerProcess>> server =
      ServerProcess::Start(ServerBinary(), DataDir(), {"--upload-budget-mib", "1"});
  ASSERT_OK(server);
  absl::StatusOr<std::unique_ptr<Client>> small = Client::Connect((*server)->target());
  ASSERT_OK(small);
  absl::StatusOr<ServerInfo> info = (*small)->GetServerInfo();
  ASSERT_OK(info);
  EXPECT_EQ(info->limits.upload_budget_bytes, int64_t{1} << 20);
  EXPECT_GT(info->limits.upload_timeout_seconds, 0);
  EXPECT_GT(info->limits.max_uploads, 0);
  // fertility_tet.vtu has 1.1 MB.
  EXPECT_TRUE(HasError((*small)->UploadFile(Data("fertility_tet.vtu")),
                       StatusCode::kResourceExhausted, "an upload of"));
  // A file within the budget goes, again and again: a load gives its bytes back.
  for (int i = 0; i < 2; ++i) {
    absl::StatusOr<MeshInfo> mesh = (*small)->UploadFile(Data("manifoldCheck0_tet.vtu"));
    ASSERT_OK(mesh) << "upload " << i;
    EXPECT_EQ(mesh->vertices, 29);
    EXPECT_EQ(mesh->tetrahedra, 24);
  }
}

// ---------------------------------------------------------------------------------------------
// What the client refuses itself, before anything is sent (no server listens on port 1).

class UploadFileArguments : public ::testing::Test {
 protected:
  void SetUp() override {
    ASSERT_FALSE(dir_.path().empty());
    absl::StatusOr<std::unique_ptr<Client>> client = Client::Connect("127.0.0.1:1");
    ASSERT_OK(client);
    client_ = *std::move(client);
  }
  std::string Pvd(const std::string& entry) {
    const fs::path pvd = dir_.path() / "series.pvd";
    WriteFile(pvd,
              "<VTKFile type=\"Collection\"><Collection>\n"
              "<DataSet timestep=\"0\" file=\"a.vtu\"/>\n"
              "<DataSet timestep=\"1\" file=\"" +
                  entry + "\"/>\n</Collection></VTKFile>\n");
    WriteFile(dir_.path() / "a.vtu", "a");
    return pvd.string();
  }

  TempDir dir_;
  std::unique_ptr<Client> client_;
};

TEST_F(UploadFileArguments, PvdEntriesOutsideItsFolderAreRefused) {
  for (const std::string entry : {"../b.vtu", "/tmp/b.vtu", "sub/../../b.vtu"}) {
    SCOPED_TRACE(entry);
    EXPECT_TRUE(HasError(client_->UploadFile(Pvd(entry)), StatusCode::kInvalidArgument,
                         "series.pvd: DataSet 1 file '" + entry + "'"));
  }
  EXPECT_TRUE(HasError(client_->UploadFile(Pvd("missing.vtu")), StatusCode::kNotFound,
                       "DataSet 1 file 'missing.vtu': no file"));
  EXPECT_TRUE(HasError(client_->UploadFile(Pvd("")), StatusCode::kInvalidArgument,
                       "DataSet 1 file '' is empty"));
  // Inside its folder, it goes as far as the server (which is not there); XML's references are
  // decoded.
  WriteFile(dir_.path() / "sub/b.vtu", "b");
  EXPECT_TRUE(HasError(client_->UploadFile(Pvd("sub/./b.vtu")), StatusCode::kUnavailable));
  WriteFile(dir_.path() / "b&c>.vtu", "b");
  EXPECT_TRUE(HasError(client_->UploadFile(Pvd("b&amp;c&#62;.vtu")), StatusCode::kUnavailable));
  EXPECT_TRUE(HasError(client_->UploadFile(Pvd("a.vtu\"/><DataSet file=\"")),
                       StatusCode::kInvalidArgument, "DataSet 2 file '' is empty"));
  WriteFile(dir_.path() / "cut.pvd", "<VTKFile><Collection><DataSet file=\"a.vtu");
  EXPECT_TRUE(HasError(client_->UploadFile((dir_.path() / "cut.pvd").string()),
                       StatusCode::kInvalidArgument, "cut.pvd: not a ParaView collection"));
}

TEST_F(UploadFileArguments, FilesAndOptionsAreChecked) {
  WriteFile(dir_.path() / "a.vtu", "a");
  WriteFile(dir_.path() / "a.obj", "a");
  const std::string vtu = (dir_.path() / "a.vtu").string();
  EXPECT_TRUE(HasError(client_->UploadFile((dir_.path() / "a.obj").string()),
                       StatusCode::kInvalidArgument, "is not a .vtu, .vtk, .vti or .pvd file"));
  EXPECT_TRUE(HasError(client_->UploadFile((dir_.path() / "none.vtu").string()),
                       StatusCode::kNotFound, "none.vtu"));
  EXPECT_TRUE(HasError(client_->UploadFile(vtu, {.chunk_bytes = 0}), StatusCode::kInvalidArgument,
                       "options.chunk_bytes"));
  EXPECT_TRUE(HasError(client_->UploadFile(vtu, {.max_resumes = -1}), StatusCode::kInvalidArgument,
                       "options.max_resumes"));
  EXPECT_TRUE(HasError(client_->UploadFile(vtu, {.partition = {.block_size = -1}}),
                       StatusCode::kInvalidArgument, "partition.block_size"));
  WriteFile(dir_.path() / "abc.vtu", "abc");
  EXPECT_EQ(FileSha256((dir_.path() / "abc.vtu").string()).value_or(""),
            "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad");
  EXPECT_TRUE(HasError(FileSha256((dir_.path() / "none").string()), StatusCode::kNotFound));
}

}  // namespace
}  // namespace actopo::client::testing
