// An actopo-server child process for tests: started on a free loopback port, stopped (SIGTERM,
// then SIGKILL) when the object goes. It also dies with the test process (PR_SET_PDEATHSIG).
#ifndef ACTOPO_CLIENT_TESTS_TESTING_SERVER_PROCESS_H_
#define ACTOPO_CLIENT_TESTS_TESTING_SERVER_PROCESS_H_

#include <sys/types.h>

#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "absl/status/statusor.h"

namespace actopo::testing {

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
  ServerProcess(pid_t pid, int out) : pid_(pid), out_(out) {}

  pid_t pid_;
  int out_;  // read end of the child's stdout
  std::string target_;
  int port_ = 0;
  std::thread drain_;  // reads the child's stdout after the first line, so it never blocks
};

}  // namespace actopo::testing

#endif  // ACTOPO_CLIENT_TESTS_TESTING_SERVER_PROCESS_H_
