#include "server/service/server.h"

#include <grpcpp/ext/proto_server_reflection_plugin.h>
#include <grpcpp/health_check_service_interface.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <thread>

#include "absl/strings/str_cat.h"
#include "server/core/status_macros.h"
#include "server/service/ids.h"
#include "server/service/memory_budget.h"
#include "server/service/mesh_registry.h"
#include "server/service/metrics.h"
#include "server/service/service.h"
#include "server/service/session_manager.h"
#include "server/service/upload_spool.h"

namespace actopo::service {
namespace {

absl::StatusOr<std::string> ReadFile(const std::string& path, const std::string& flag) {
  std::ifstream in(path);
  if (!in) return absl::NotFoundError(absl::StrCat(flag, ": cannot read '", path, "'"));
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

int64_t DefaultBudget() {
  const int64_t pages = sysconf(_SC_PHYS_PAGES), page = sysconf(_SC_PAGESIZE);
  return pages > 0 && page > 0 ? pages * page / 4 * 3 : int64_t(8) << 30;
}

// The executors' threads. Loads and openings use every core inside (partitioning, encoding,
// precomputing): a few at once, the rest wait in order. Relation answers are short and
// single-threaded: one per core. A running job holds at least one of the sessions' engine
// threads, so --max-engine-threads (and the session limit) bound how many can run at once.
ServiceThreads Threads(const ServerOptions& o) {
  const int cores = int(std::max(1u, std::thread::hardware_concurrency()));
  return {.background = 4,
          .relations = std::max(cores, 2),
          .jobs = std::max(1, std::min(o.max_engine_threads, o.max_sessions))};
}

}  // namespace

struct Server::State {
  std::unique_ptr<MemoryBudget> budget;
  std::unique_ptr<Metrics> metrics;
  std::unique_ptr<MeshRegistry> meshes;
  std::unique_ptr<SessionManager> sessions;
  std::unique_ptr<UploadSpool> spool;
  std::unique_ptr<TopologyServiceImpl> service;
  std::unique_ptr<grpc::Server> server;
  bool shut_down = false;
};

Server::Server() : state_(std::make_unique<State>()) {}

Server::~Server() { Shutdown(absl::Seconds(1)); }

absl::StatusOr<std::unique_ptr<Server>> Server::Start(const ServerOptions& o) {
  auto server = std::unique_ptr<Server>(new Server());
  State& s = *server->state_;
  s.budget = std::make_unique<MemoryBudget>(o.memory_budget_bytes > 0 ? o.memory_budget_bytes
                                                                      : DefaultBudget());
  ASSIGN_OR_RETURN(s.metrics, Metrics::Create(o.host, o.metrics_port));
  s.meshes = std::make_unique<MeshRegistry>(
      MeshRegistryOptions{
          .data_dir = o.data_dir, .max_meshes = o.max_meshes, .reader = o.mesh_reader},
      s.budget.get());
  s.sessions =
      std::make_unique<SessionManager>(SessionLimits{.max_sessions = o.max_sessions,
                                                     .max_engine_threads = o.max_engine_threads,
                                                     .idle_timeout = o.session_idle_timeout},
                                       s.budget.get());
  // Without --upload-dir, a folder of this process's own in the temporary directory; what
  // killed servers left there beside it goes first.
  constexpr char kUploadPrefix[] = "actopo-uploads-";
  if (o.upload_dir.empty()) {
    UploadSpool::RemoveAbandoned(std::filesystem::temp_directory_path(), kUploadPrefix);
  }
  const std::filesystem::path upload_dir =
      !o.upload_dir.empty() ? std::filesystem::path(o.upload_dir)
                            : std::filesystem::temp_directory_path() /
                                  absl::StrCat(kUploadPrefix, ::getpid(), "-", NewId("s"));
  ASSIGN_OR_RETURN(
      s.spool,
      UploadSpool::Open({.dir = upload_dir,
                         .budget_bytes = o.upload_budget_bytes,
                         .timeout = std::chrono::seconds(absl::ToInt64Seconds(o.upload_timeout)),
                         .max_uploads = o.max_uploads}));
  s.service = std::make_unique<TopologyServiceImpl>(
      s.meshes.get(), s.sessions.get(), s.spool.get(), s.budget.get(), s.metrics.get(),
      ServiceLimits{.max_batch_size = o.max_batch_size,
                    .max_message_bytes = o.max_message_bytes,
                    .max_meshes = o.max_meshes,
                    .max_sessions = o.max_sessions,
                    .max_engine_threads = o.max_engine_threads,
                    .session_idle_timeout_seconds = absl::ToInt64Seconds(o.session_idle_timeout),
                    .upload_budget_bytes = o.upload_budget_bytes,
                    .upload_timeout_seconds = absl::ToInt64Seconds(o.upload_timeout),
                    .max_uploads = o.max_uploads},
      Threads(o), o.token, o.before_work);

  std::shared_ptr<grpc::ServerCredentials> credentials = grpc::InsecureServerCredentials();
  if (!o.tls_cert_file.empty() || !o.tls_key_file.empty()) {
    if (o.tls_cert_file.empty() || o.tls_key_file.empty()) {
      return absl::InvalidArgumentError("--tls-cert and --tls-key go together");
    }
    grpc::SslServerCredentialsOptions ssl;
    ASSIGN_OR_RETURN(std::string cert, ReadFile(o.tls_cert_file, "--tls-cert"));
    ASSIGN_OR_RETURN(std::string key, ReadFile(o.tls_key_file, "--tls-key"));
    ssl.pem_key_cert_pairs.push_back({key, cert});
    credentials = grpc::SslServerCredentials(ssl);
  }
  grpc::EnableDefaultHealthCheckService(true);
  grpc::reflection::InitProtoReflectionServerBuilderPlugin();
  grpc::ServerBuilder builder;
  builder.AddListeningPort(absl::StrCat(o.host, ":", o.port), credentials, &server->port_);
  builder.RegisterService(s.service.get());
  builder.SetMaxReceiveMessageSize(int(o.max_message_bytes));
  builder.SetMaxSendMessageSize(int(o.max_message_bytes));
  // Clients ping every minute while a call waits (a long load sends nothing for minutes): gRPC's
  // default (one ping per 5 minutes without data, then GOAWAY "too many pings") would cut them.
  // The server pings too, so that a client gone without a word frees what its calls hold (an
  // upload being written) within about a minute and a half.
  builder.AddChannelArgument(GRPC_ARG_HTTP2_MIN_RECV_PING_INTERVAL_WITHOUT_DATA_MS, 30'000);
  builder.AddChannelArgument(GRPC_ARG_KEEPALIVE_TIME_MS, 60'000);
  builder.AddChannelArgument(GRPC_ARG_KEEPALIVE_TIMEOUT_MS, 20'000);
  s.server = builder.BuildAndStart();
  if (s.server == nullptr || server->port_ == 0) {
    return absl::UnavailableError(
        absl::StrCat("--port: cannot listen on ", o.host, ":", o.port, " (in use?)"));
  }
  s.server->GetHealthCheckService()->SetServingStatus(true);
  s.metrics->SetGaugeSource([service = s.service.get()] { return service->Gauges(); });
  return server;
}

int Server::metrics_port() const { return state_->metrics->port(); }

int64_t Server::memory_budget_used_bytes() const { return state_->budget->used(); }

std::shared_ptr<grpc::Channel> Server::InProcessChannel() {
  return state_->server->InProcessChannel(grpc::ChannelArguments());
}

void Server::Drain() {
  State& s = *state_;
  if (s.server == nullptr) return;
  s.server->GetHealthCheckService()->SetServingStatus(false);
  s.service->Drain();
}

void Server::Shutdown(absl::Duration grace) {
  State& s = *state_;
  if (s.shut_down || s.server == nullptr) return;
  s.shut_down = true;
  Drain();
  s.server->Shutdown(std::chrono::system_clock::now() + absl::ToChronoSeconds(grace));
  s.server->Wait();
  s.metrics->SetGaugeSource(nullptr);  // the service goes before the metrics
}

void Server::Wait() { state_->server->Wait(); }

}  // namespace actopo::service
