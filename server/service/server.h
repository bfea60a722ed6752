// actopo-server as a library: options as a plain struct, BuildServer() wires the service, the
// standard health service, reflection and metrics. Tests run it in process.
//
//   ServerOptions options{.port = 0, .data_dir = "/data"};
//   ASSIGN_OR_RETURN(auto server, Server::Start(options));
//   auto channel = server->InProcessChannel();
//   ...
//   server->Shutdown(absl::Seconds(5));   // drain: health NOT_SERVING, jobs cancelled
#ifndef ACTOPO_SERVER_SERVICE_SERVER_H_
#define ACTOPO_SERVER_SERVICE_SERVER_H_

#include <grpcpp/grpcpp.h>

#include <functional>
#include <memory>
#include <string>
#include <string_view>

#include "absl/status/statusor.h"
#include "absl/time/time.h"

namespace actopo::service {

struct ServerOptions {
  std::string host = "0.0.0.0";
  int port = 50051;         // 0: pick a free port (see Server::port())
  std::string data_dir;     // LoadMesh paths are relative to it; empty: no files
  std::string mesh_reader;  // actopo-read-mesh: files read in a child; empty: in process
  int metrics_port = 0;     // Prometheus /metrics; 0: off
  int max_meshes = 16;
  int max_sessions = 64;
  int max_engine_threads = 64;
  int64_t memory_budget_bytes = 0;  // 0: 75% of physical memory
  int64_t max_message_bytes = 64 << 20;
  int max_batch_size = 1 << 20;
  absl::Duration session_idle_timeout = absl::Minutes(30);
  // Uploads (CreateUpload): their folder (empty: a folder of the system's temporary directory,
  // by process), the sizes held at once, how long one may be left alone, how many at once.
  std::string upload_dir;
  int64_t upload_budget_bytes = int64_t(8) << 30;
  absl::Duration upload_timeout = absl::Minutes(15);
  int max_uploads = 64;
  std::string tls_cert_file, tls_key_file;  // both set: TLS
  std::string token;                        // non-empty: require "authorization: Bearer TOKEN"
  // Tests only: runs on an executor's thread before the work of each load, upload, opening, job
  // ("RunJob") or relation call begins, with the RPC's name, and as each phase of a
  // LoadMeshWithProgress begins, with "LoadMeshWithProgress/PHASE" (read, partition, encode). A
  // test blocks in it to hold that work at a known point (until the call's deadline has passed, or
  // it is cancelled).
  std::function<void(std::string_view rpc)> before_work;
};

class Server {
 public:
  static absl::StatusOr<std::unique_ptr<Server>> Start(const ServerOptions& options);
  ~Server();

  int port() const { return port_; }
  int metrics_port() const;
  // Bytes of the memory budget held by meshes, sessions, uploads and loads in progress.
  int64_t memory_budget_used_bytes() const;
  std::shared_ptr<grpc::Channel> InProcessChannel();
  // Health turns NOT_SERVING, new calls get UNAVAILABLE, running jobs are cancelled; the
  // server keeps answering health checks.
  void Drain();
  // Drain(), then waits up to `grace` for calls to end and stops.
  void Shutdown(absl::Duration grace);
  void Wait();

 private:
  Server();
  struct State;
  std::unique_ptr<State> state_;
  int port_ = 0;
};

}  // namespace actopo::service

#endif  // ACTOPO_SERVER_SERVICE_SERVER_H_
