// LoadMeshWithProgress's stream, shared by the loads of a path, a series and an upload.
#ifndef ACTOPO_CLIENT_SRC_INTERNAL_LOAD_H_
#define ACTOPO_CLIENT_SRC_INTERNAL_LOAD_H_

#include <functional>
#include <memory>

#include "absl/status/statusor.h"
#include "actopo/client.h"
#include "actopo/v1/topology_service.pb.h"
#include "src/internal/core.h"

namespace actopo::client::internal {

// Calls `f` when a CancelToken is cancelled, until the result is destroyed: the token's
// OnCancel, which only a Client may call, passed in by one.
using OnCancel = std::function<std::shared_ptr<void>(std::function<void()> f)>;

// Runs `load` as a LoadMeshWithProgress call: options.progress gets each report on this thread
// (an exception thrown there cancels the load and propagates), options.cancel (through
// `on_cancel`) stops it, options.timeout (or the core's mesh_timeout) is its deadline.
absl::StatusOr<MeshInfo> LoadWithProgress(const Core& core, v1::LoadMeshRequest load,
                                          const LoadOptions& options, const OnCancel& on_cancel);

}  // namespace actopo::client::internal

#endif  // ACTOPO_CLIENT_SRC_INTERNAL_LOAD_H_
