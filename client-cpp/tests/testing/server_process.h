// Child processes for tests: any program (ChildProcess), and an actopo-server started on a free
// loopback port (ServerProcess). Each is stopped (SIGTERM, then SIGKILL) when the object goes,
// and dies with the test process (PR_SET_PDEATHSIG).
#ifndef ACTOPO_CLIENT_TESTS_TESTING_SERVER_PROCESS_H_
#define ACTOPO_CLIENT_TESTS_TESTING_SERVER_PROCESS_H_

#include <sys/types.h>

#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "absl/status/statusor.h"

namespace actopo::client::testing {

class ChildProcess {
 public:
  // Runs args[0] with the arguments after it, without $ACTOPO_TOKEN in its environment, its
  // stdout into `stdout_fd` (-1: the test's own).
  static absl::StatusOr<std::unique_ptr<ChildProcess>> Start(const std::vector<std::string>& args,
                                                             int stdout_fd = -1);
  ChildProcess(const ChildProcess&) = delete;
  ChildProcess& operator=(const ChildProcess&) = delete;
  ~ChildProcess();

  pid_t pid() const { return pid_; }
  // Whether it still runs (not exited, or exited and not yet reaped by this object).
  bool running();

 private:
  explicit ChildProcess(pid_t pid) : pid_(pid) {}
  pid_t pid_;
  bool reaped_ = false;
};

class ServerProcess {
 public:
  // Runs `binary --host 127.0.0.1 --port 0 --data-dir DATA_DIR EXTRA...` (without
  // $ACTOPO_TOKEN in its environment) and waits for its "listening on" line.
  static absl::StatusOr<std::unique_ptr<ServerProcess>> Start(
      const std::string& binary, const std::string& data_dir,
      const std::vector<std::string>& extra = {});
  ServerProcess(const ServerProcess&) = delete;
  ServerProcess& operator=(const ServerProcess&) = delete;
  ~ServerProcess();

  // "127.0.0.1:PORT".
  const std::string& target() const { return target_; }
  int port() const { return port_; }

 private:
  ServerProcess(std::unique_ptr<ChildProcess> child, int out)
      : child_(std::move(child)), out_(out) {}

  std::unique_ptr<ChildProcess> child_;
  int out_;  // read end of the child's stdout
  std::string target_;
  int port_ = 0;
  std::thread drain_;  // reads the child's stdout after the first line, so it never blocks
};

}  // namespace actopo::client::testing

#endif  // ACTOPO_CLIENT_TESTS_TESTING_SERVER_PROCESS_H_
