// TopologyServiceImpl::Unary and ::Offload: a unary call answered inline, or from an executor
// (service.h). Included by the .cc files that answer unary calls; an offloaded call's reactor
// deletes itself when gRPC is done with it.
#ifndef ACTOPO_SERVER_SERVICE_OFFLOAD_H_
#define ACTOPO_SERVER_SERVICE_OFFLOAD_H_

#include <grpcpp/grpcpp.h>

#include <atomic>
#include <memory>
#include <string_view>

#include "server/core/process_memory.h"
#include "server/service/service.h"
#include "server/service/wire.h"

namespace actopo::service {

template <class Fn>
grpc::ServerUnaryReactor* TopologyServiceImpl::Unary(grpc::CallbackServerContext* context,
                                                     std::string_view rpc, Fn&& fn) {
  grpc::ServerUnaryReactor* reactor = context->DefaultReactor();
  absl::Status status = Admit(context);
  if (status.ok()) status = fn();
  Count(rpc, status);
  reactor->Finish(ToGrpcStatus(status));
  return reactor;
}

// The cancel flag of an offloaded unary call: set when the client cancels, the deadline passes
// or the server drains.
class OffloadedUnaryReactor final : public grpc::ServerUnaryReactor {
 public:
  void OnCancel() override { cancel_->store(true); }
  void OnDone() override { delete this; }
  const Executor::CancelFlag& cancel() const { return cancel_; }

 private:
  const Executor::CancelFlag cancel_ = std::make_shared<std::atomic<bool>>(false);
};

template <class Fn>
grpc::ServerUnaryReactor* TopologyServiceImpl::Offload(Executor& executor,
                                                       grpc::CallbackServerContext* context,
                                                       std::string_view rpc, Fn fn) {
  auto* reactor = new OffloadedUnaryReactor();
  if (absl::Status admitted = Admit(context); !admitted.ok()) {
    Count(rpc, admitted);
    reactor->Finish(ToGrpcStatus(admitted));
    return reactor;
  }
  const Progress::Clock::time_point deadline = SteadyDeadline(*context);
  executor.Run(reactor->cancel(), [this, &executor, reactor, rpc, deadline, fn = std::move(fn)] {
    BeforeWork(rpc);
    const absl::Status status =
        fn(Progress({.cancel = reactor->cancel().get(), .deadline = deadline}));
    // What a failed or stopped load or opening had built goes back to the system. Not for a
    // relation call: a bad id is an answer like any other, and malloc_trim is not cheap.
    if (!status.ok() && &executor == &background_) ReleaseFreeMemory();
    Count(rpc, status);
    reactor->Finish(ToGrpcStatus(status));  // nothing touches the reactor after this
  });
  return reactor;
}

}  // namespace actopo::service

#endif  // ACTOPO_SERVER_SERVICE_OFFLOAD_H_
