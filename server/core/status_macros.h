// Small stand-ins for the status macros that Debian's Abseil (20220623) does not ship.
//
//   RETURN_IF_ERROR(ValidateMesh(mesh));
//   ASSIGN_OR_RETURN(Topology topology, Topology::Build(mesh, blocks));
#ifndef ACTOPO_SERVER_CORE_STATUS_MACROS_H_
#define ACTOPO_SERVER_CORE_STATUS_MACROS_H_

#include "absl/status/status.h"
#include "absl/status/statusor.h"

#define ACTOPO_CONCAT_INNER_(a, b) a##b
#define ACTOPO_CONCAT_(a, b) ACTOPO_CONCAT_INNER_(a, b)

#define RETURN_IF_ERROR(expr)                                         \
  do {                                                                \
    if (absl::Status actopo_status_ = (expr); !actopo_status_.ok()) { \
      return actopo_status_;                                          \
    }                                                                 \
  } while (0)

#define ACTOPO_ASSIGN_OR_RETURN_IMPL_(tmp, lhs, expr) \
  auto tmp = (expr);                                  \
  if (!tmp.ok()) return std::move(tmp).status();      \
  lhs = std::move(*tmp)

#define ASSIGN_OR_RETURN(lhs, expr) \
  ACTOPO_ASSIGN_OR_RETURN_IMPL_(ACTOPO_CONCAT_(actopo_statusor_, __LINE__), lhs, expr)

#endif  // ACTOPO_SERVER_CORE_STATUS_MACROS_H_
