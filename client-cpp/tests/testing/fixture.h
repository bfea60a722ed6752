// The test fixture: one actopo-server for the whole test binary (started on first use, stopped at
// exit), a Client on it, and helpers that clean up the meshes and sessions a test makes.
//
// Environment: ACTOPO_SERVER_BIN, ACTOPO_BENCH_BIN, ACTOPO_DATA_DIR override the defaults (the
// main project's build/ beside client-cpp, and ../shared/data).
#ifndef ACTOPO_CLIENT_TESTS_TESTING_FIXTURE_H_
#define ACTOPO_CLIENT_TESTS_TESTING_FIXTURE_H_

#include <gtest/gtest.h>

#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "actopo/client.h"
#include "tests/testing/server_process.h"
#include "tests/testing/skip.h"  // the repository's tests/testing, for ACTOPO_SKIP

namespace actopo::client::testing {

std::string ServerBinary();
std::string BenchBinary();
std::string DataDir();

// The shared server's limits (tests rely on them).
inline constexpr int kSharedMaxBatchSize = 64;

// actopo-bench's "result" for a file under the data directory, run in-process; a null JSON
// and a test failure if it cannot run.
nlohmann::json BenchResult(const std::string& file, const std::string& scalar,
                           const std::string& algorithm);
// The same over several fields (actopo-bench --scalars: "F1,F2,..." or "all"), e.g. the
// matrices of diagram-distance.
nlohmann::json BenchSeriesResult(const std::string& file, const std::string& scalars,
                                 const std::string& algorithm);

// Upstream TTK's result of `section` (critical_points, discrete_gradient, morse_smale,
// persistence_diagram) for `field` on `file`, from expected-ttk.json under the data directory; a
// null JSON and a test failure if it is missing.
nlohmann::json TtkReference(const std::string& file, const std::string& field,
                            const std::string& section);

// ASSERT_OK(expr) / EXPECT_OK(expr) for Status and StatusOr: `expr` is evaluated once, and
// more context can be streamed in (EXPECT_OK(call) << "while ...").
inline const absl::Status& StatusOf(const absl::Status& s) { return s; }
template <class T>
const absl::Status& StatusOf(const absl::StatusOr<T>& s) {
  return s.status();
}
#define ACTOPO_CHECK_OK_(expr, on_failure)                                               \
  switch (0)                                                                             \
  case 0:                                                                                \
  default:                                                                               \
    if (const ::absl::Status actopo_status_ = ::actopo::client::testing::StatusOf(expr); \
        actopo_status_.ok()) {                                                           \
    } else                                                                               \
      on_failure() << #expr << ": " << actopo_status_ << " "
#define ASSERT_OK(expr) ACTOPO_CHECK_OK_(expr, GTEST_FAIL)
#define EXPECT_OK(expr) ACTOPO_CHECK_OK_(expr, ADD_FAILURE)

// Expects `status` to have `code` and a message containing `part`.
::testing::AssertionResult HasError(const absl::Status& status, absl::StatusCode code,
                                    const std::string& part = "");
template <class T>
::testing::AssertionResult HasError(const absl::StatusOr<T>& s, absl::StatusCode code,
                                    const std::string& part = "") {
  return HasError(s.status(), code, part);
}

class ServerTest : public ::testing::Test {
 protected:
  void SetUp() override;
  void TearDown() override;

  // A sample loaded for this test (deleted after it); fails the test on error.
  std::string LoadSample(const std::string& name, int32_t block_size = 0);
  // A session for this test (closed after it).
  std::string Open(const std::string& mesh_id, const SessionOptions& options = {});
  // The id of a mesh this test made (deleted after it), or "" and a failure if it was not made.
  std::string Keep(const absl::StatusOr<MeshInfo>& mesh);
  // fertility_tet.vtu, loaded once for the whole binary.
  std::string Fertility();

  Client& client() { return *client_; }
  const std::string& target() const;
  // Holds the shared server's work named `work` (ServerProcess::Hold).
  std::unique_ptr<WorkHold> Hold(const std::string& work) const;

  Client* client_ = nullptr;
  std::vector<std::string> meshes_, sessions_;
};

}  // namespace actopo::client::testing

#endif  // ACTOPO_CLIENT_TESTS_TESTING_FIXTURE_H_
