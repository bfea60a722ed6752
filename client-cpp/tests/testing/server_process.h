// Child processes for tests: any program (ChildProcess), and an actopo-server started on a free
// loopback port (ServerProcess). Each is stopped (SIGTERM, then SIGKILL) when the object goes,
// and dies with the test process (PR_SET_PDEATHSIG). Tests wait for events, never for time:
// WaitUntil for a condition, ServerProcess::Hold to keep the server's work from ending.
#ifndef ACTOPO_CLIENT_TESTS_TESTING_SERVER_PROCESS_H_
#define ACTOPO_CLIENT_TESTS_TESTING_SERVER_PROCESS_H_

#include <sys/types.h>

#include <chrono>
#include <functional>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "absl/status/statusor.h"

namespace actopo::client::testing {

// Whether `done` holds within `timeout` (checked now, then every 10 ms): the one way these tests
// wait for something another process does.
bool WaitUntil(const std::function<bool()>& done,
               std::chrono::milliseconds timeout = std::chrono::seconds(60));

// Holds the server's work of one name at its start while it lives (ServerProcess::Hold).
class WorkHold {
 public:
  WorkHold(const WorkHold&) = delete;
  WorkHold& operator=(const WorkHold&) = delete;
  ~WorkHold() { Release(); }

  // Whether such work has arrived and waits (within `timeout`).
  bool WaitHeld(std::chrono::milliseconds timeout = std::chrono::seconds(60)) const;
  // Lets the held work, and any that comes later, go on.
  void Release();

 private:
  friend class ServerProcess;
  explicit WorkHold(std::string file) : file_(std::move(file)) {}
  std::string file_;  // while it exists, the server holds the work
};

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

  // Holds the work named `work` at its start until the hold is released or goes: "RunJob" (a
  // job, after the client has its id, before it runs), "LoadMeshWithProgress" (the clients'
  // loads), "UploadMesh", "OpenSession" (actopo-server --test-gate-dir, which Start passes).
  // A test so makes a deadline pass, or cancels, while the work has surely not ended.
  std::unique_ptr<WorkHold> Hold(const std::string& work) const;

 private:
  ServerProcess(std::unique_ptr<ChildProcess> child, int out)
      : child_(std::move(child)), out_(out) {}

  std::unique_ptr<ChildProcess> child_;
  int out_;               // read end of the child's stdout
  std::string gate_dir_;  // --test-gate-dir, removed with the server
  std::string target_;
  int port_ = 0;
  std::thread drain_;  // reads the child's stdout after the first line, so it never blocks
};

}  // namespace actopo::client::testing

#endif  // ACTOPO_CLIENT_TESTS_TESTING_SERVER_PROCESS_H_
