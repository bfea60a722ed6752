// The state a Client shares with its streams: the channel, the stub and the options; and the one
// place that makes call contexts and turns grpc::Status into absl::Status.
#ifndef ACTOPO_CLIENT_SRC_INTERNAL_CORE_H_
#define ACTOPO_CLIENT_SRC_INTERNAL_CORE_H_

#include <grpcpp/grpcpp.h>

#include <atomic>
#include <chrono>
#include <memory>
#include <string>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "actopo/client.h"
#include "actopo/v1/topology_service.grpc.pb.h"

namespace actopo::client::internal {

// Debian's Abseil has no status macros.
#define ACTOPO_RETURN_IF_ERROR(expr)            \
  do {                                          \
    if (::absl::Status _s = (expr); !_s.ok()) { \
      return _s;                                \
    }                                           \
  } while (0)

#define ACTOPO_CONCAT_INNER(a, b) a##b
#define ACTOPO_CONCAT(a, b) ACTOPO_CONCAT_INNER(a, b)
#define ACTOPO_ASSIGN_OR_RETURN(lhs, expr) \
  ACTOPO_ASSIGN_OR_RETURN_IMPL(ACTOPO_CONCAT(_statusor_, __LINE__), lhs, expr)
#define ACTOPO_ASSIGN_OR_RETURN_IMPL(tmp, lhs, expr) \
  auto tmp = (expr);                                 \
  if (!tmp.ok()) return tmp.status();                \
  lhs = std::move(*tmp)

// gRPC and Abseil share their code numbers; the message is kept as the server wrote it.
absl::Status FromGrpc(const grpc::Status& status);

struct Core {
  std::string target;
  ClientOptions options;  // options.affinity_key is resolved (never empty)
  std::shared_ptr<grpc::Channel> channel;
  std::unique_ptr<v1::TopologyService::Stub> stub;
  // What made the channel, for StubOnOwnConnection.
  std::shared_ptr<grpc::ChannelCredentials> credentials;
  grpc::ChannelArguments channel_args;
  std::atomic<int64_t> max_batch_size{0};  // from GetServerInfo, 0 until asked

  // A context carrying the token and the affinity key, with a deadline `timeout` from now (none if
  // zero).
  std::unique_ptr<grpc::ClientContext> Context(std::chrono::milliseconds timeout) const;
  std::unique_ptr<grpc::ClientContext> QuickContext() const {
    return Context(options.default_timeout);
  }
  std::unique_ptr<grpc::ClientContext> MeshContext() const { return Context(options.mesh_timeout); }

  // A stub on a channel with a connection of its own (gRPC otherwise shares one connection
  // among a process's channels to the same target with the same arguments): for a call that
  // must not wait behind what a stopped stream left queued in the shared one.
  std::unique_ptr<v1::TopologyService::Stub> StubOnOwnConnection() const;
  // One unary call: client->Unary(&Stub::GetMesh, request, QuickContext()).
  template <class Request, class Response>
  absl::StatusOr<Response> Unary(grpc::Status (v1::TopologyService::Stub::*method)(
                                     grpc::ClientContext*, const Request&, Response*),
                                 const Request& request,
                                 std::unique_ptr<grpc::ClientContext> context) const {
    Response response;
    const grpc::Status status = (stub.get()->*method)(context.get(), request, &response);
    if (!status.ok()) return FromGrpc(status);
    return response;
  }
};

// Connects (lazily unless options.connect_timeout > 0).
absl::StatusOr<std::shared_ptr<Core>> NewCore(std::string target, const ClientOptions& options);

}  // namespace actopo::client::internal

#endif  // ACTOPO_CLIENT_SRC_INTERNAL_CORE_H_
