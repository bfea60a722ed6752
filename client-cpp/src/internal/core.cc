#include "src/internal/core.h"

#include <cstdlib>
#include <random>

#include "absl/strings/escaping.h"
#include "absl/strings/str_cat.h"

namespace actopo::client::internal {
namespace {

// The retry policy of ClientOptions::retries, the same as the Python client's.
std::string RetryServiceConfig() {
  std::string names;
  for (const char* method : {"GetServerInfo", "ListMeshes", "GetMesh", "ListSessions", "GetSession",
                             "GetSessionStats", "GetRelation", "GetRelationBatch", "GetUpload"}) {
    absl::StrAppend(&names, names.empty() ? "" : ",", "{\"service\":\"",
                    v1::TopologyService::service_full_name(), "\",\"method\":\"", method, "\"}");
  }
  return absl::StrCat(
      "{\"methodConfig\":[{\"name\":[", names,
      "],\"retryPolicy\":{\"maxAttempts\":5,\"initialBackoff\":\"0.2s\",\"maxBackoff\":\"2s\","
      "\"backoffMultiplier\":2,\"retryableStatusCodes\":[\"UNAVAILABLE\"]}}]}");
}

// The affinity key: given, else $ACTOPO_AFFINITY_KEY, else 128 random bits in hex.
absl::StatusOr<std::string> AffinityKey(std::string key) {
  const char* source = "options.affinity_key";
  if (key.empty()) {
    const char* env = std::getenv("ACTOPO_AFFINITY_KEY");
    if (env != nullptr) key = env;
    source = "ACTOPO_AFFINITY_KEY";
  }
  if (key.empty()) {
    std::random_device random;
    for (int i = 0; i < 4; ++i) absl::StrAppend(&key, absl::Hex(random(), absl::kZeroPad8));
    return key;
  }
  for (const char c : key) {
    if (c < 0x20 || c > 0x7e) {
      return absl::InvalidArgumentError(absl::StrCat(
          source, ": '", absl::CHexEscape(key),
          "' is not printable ASCII (it travels as the gRPC metadata x-actopo-session)"));
    }
  }
  return key;
}

}  // namespace

absl::Status FromGrpc(const grpc::Status& status) {
  if (status.ok()) return absl::OkStatus();
  return absl::Status(static_cast<absl::StatusCode>(status.error_code()), status.error_message());
}

std::unique_ptr<grpc::ClientContext> Core::Context(std::chrono::milliseconds timeout) const {
  auto context = std::make_unique<grpc::ClientContext>();
  if (!options.token.empty()) {
    context->AddMetadata("authorization", "Bearer " + options.token);
  }
  context->AddMetadata("x-actopo-session", options.affinity_key);
  if (timeout.count() > 0) context->set_deadline(std::chrono::system_clock::now() + timeout);
  return context;
}

std::unique_ptr<v1::TopologyService::Stub> Core::StubOnOwnConnection() const {
  grpc::ChannelArguments args = channel_args;
  args.SetInt(GRPC_ARG_USE_LOCAL_SUBCHANNEL_POOL, 1);
  return v1::TopologyService::NewStub(grpc::CreateCustomChannel(target, credentials, args));
}

absl::StatusOr<std::shared_ptr<Core>> NewCore(std::string target, const ClientOptions& options) {
  if (target.empty()) {
    const char* env = std::getenv("ACTOPO_SERVER");
    if (env != nullptr) target = env;
  }
  if (target.empty()) {
    return absl::InvalidArgumentError(
        "target: no server given; pass \"HOST:PORT\" or set ACTOPO_SERVER");
  }
  if (options.max_message_bytes <= 0) {
    return absl::InvalidArgumentError(
        absl::StrCat("options.max_message_bytes: ", options.max_message_bytes, " is not positive"));
  }
  std::shared_ptr<grpc::ChannelCredentials> credentials;
  if (options.use_tls) {
    grpc::SslCredentialsOptions ssl;
    ssl.pem_root_certs = options.tls_root_certs;
    credentials = grpc::SslCredentials(ssl);
  } else if (!options.tls_root_certs.empty()) {
    return absl::InvalidArgumentError(
        "options.tls_root_certs: given without use_tls; set use_tls = true");
  } else {
    credentials = grpc::InsecureChannelCredentials();
  }
  grpc::ChannelArguments args;
  args.SetMaxReceiveMessageSize(options.max_message_bytes);
  args.SetMaxSendMessageSize(options.max_message_bytes);
  // A ping every minute while calls are in flight: a job can be silent for long, and a dead
  // peer should not hang the client. Never on an idle channel, which servers would refuse.
  args.SetInt(GRPC_ARG_KEEPALIVE_TIME_MS, 60'000);
  args.SetInt(GRPC_ARG_KEEPALIVE_TIMEOUT_MS, 20'000);
  args.SetInt(GRPC_ARG_KEEPALIVE_PERMIT_WITHOUT_CALLS, 0);
  if (options.retries) {
    args.SetInt(GRPC_ARG_ENABLE_RETRIES, 1);
    args.SetServiceConfigJSON(RetryServiceConfig());
    // A batch of 65536 ids is 512 KiB, over gRPC's default 256 KiB kept for retrying.
    args.SetInt(GRPC_ARG_PER_RPC_RETRY_BUFFER_SIZE, 4 << 20);
    // gRPC waits 1 s after a lost connection, then longer up to 2 min: too long for the
    // attempts above to meet a restarted server.
    args.SetInt(GRPC_ARG_INITIAL_RECONNECT_BACKOFF_MS, 100);
    args.SetInt(GRPC_ARG_MAX_RECONNECT_BACKOFF_MS, 1'000);
  } else {
    args.SetInt(GRPC_ARG_ENABLE_RETRIES, 0);
  }

  auto core = std::make_shared<Core>();
  core->target = target;
  core->options = options;
  ACTOPO_ASSIGN_OR_RETURN(core->options.affinity_key, AffinityKey(options.affinity_key));
  core->channel = grpc::CreateCustomChannel(target, credentials, args);
  core->credentials = credentials;
  core->channel_args = args;
  core->stub = v1::TopologyService::NewStub(core->channel);
  if (options.connect_timeout.count() > 0 &&
      !core->channel->WaitForConnected(std::chrono::system_clock::now() +
                                       options.connect_timeout)) {
    return absl::UnavailableError(absl::StrCat("target: could not connect to ", target, " within ",
                                               options.connect_timeout.count(), " ms"));
  }
  return core;
}

}  // namespace actopo::client::internal
