// Tests: the value of a StatusOr, or the test fails naming the status. Dereferencing a StatusOr
// that holds an error is undefined behaviour; OkValue throws instead, which GoogleTest reports as
// a failure of the test with the status's message, and the other tests go on.
//
//   const Mesh mesh = OkValue(io::MakeSample("jittered:6"));
//   EXPECT_EQ(OkValue(RunCriticalPoints(structure, order, {})).counts, want);
#ifndef ACTOPO_SERVER_CORE_TESTING_STATUS_H_
#define ACTOPO_SERVER_CORE_TESTING_STATUS_H_

#include <stdexcept>
#include <string>
#include <utility>

#include "absl/status/statusor.h"

namespace actopo {

template <class T>
T OkValue(absl::StatusOr<T> value) {
  if (!value.ok()) throw std::runtime_error("not OK: " + std::string(value.status().ToString()));
  return *std::move(value);
}

}  // namespace actopo

#endif  // ACTOPO_SERVER_CORE_TESTING_STATUS_H_
