#include "tests/testing/server_process.h"

#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <sys/prctl.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <thread>

#include "absl/strings/str_cat.h"

extern char** environ;

namespace actopo::client::testing {
namespace {

constexpr std::string_view kListening = "actopo-server listening on ";

// Reads one line from `fd` within `timeout`; false on EOF or timeout.
bool ReadLine(int fd, std::chrono::seconds timeout, std::string& line) {
  const auto end = std::chrono::steady_clock::now() + timeout;
  line.clear();
  while (true) {
    const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(
        end - std::chrono::steady_clock::now());
    if (left.count() <= 0) return false;
    pollfd p{.fd = fd, .events = POLLIN, .revents = 0};
    const int ready = poll(&p, 1, int(left.count()));
    if (ready < 0 && errno == EINTR) continue;
    if (ready <= 0) return false;
    char c;
    const ssize_t n = read(fd, &c, 1);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) return false;
    if (c == '\n') return true;
    line.push_back(c);
  }
}

// Waits up to `timeout` for `pid` to exit; true once it has been reaped.
bool WaitFor(pid_t pid, std::chrono::milliseconds timeout, int* status) {
  return WaitUntil(
      [&] {
        const pid_t r = waitpid(pid, status, WNOHANG);
        return r == pid || (r < 0 && errno == ECHILD);
      },
      timeout);
}

}  // namespace

bool WaitUntil(const std::function<bool()>& done, std::chrono::milliseconds timeout) {
  const auto end = std::chrono::steady_clock::now() + timeout;
  while (!done()) {
    if (std::chrono::steady_clock::now() >= end) return false;
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  return true;
}

bool WorkHold::WaitHeld(std::chrono::milliseconds timeout) const {
  return WaitUntil([&] { return std::filesystem::exists(file_ + ".held"); }, timeout);
}

void WorkHold::Release() {
  std::error_code ec;
  std::filesystem::remove(file_, ec);
}

absl::StatusOr<std::unique_ptr<ChildProcess>> ChildProcess::Start(
    const std::vector<std::string>& args, int stdout_fd) {
  if (args.empty() || access(args[0].c_str(), X_OK) != 0) {
    return absl::NotFoundError(
        absl::StrCat("no program to run at '", args.empty() ? "" : args[0], "'"));
  }
  // Everything the child needs is built before fork: between fork and exec only
  // async-signal-safe calls are allowed.
  std::vector<std::string> copy = args;
  std::vector<char*> argv;
  for (std::string& a : copy) argv.push_back(a.data());
  argv.push_back(nullptr);
  std::vector<char*> envp;
  for (char** e = environ; *e != nullptr; ++e) {
    if (std::strncmp(*e, "ACTOPO_TOKEN=", 13) != 0) envp.push_back(*e);
  }
  envp.push_back(nullptr);

  const pid_t parent = getpid();
  const pid_t pid = fork();
  if (pid < 0) return absl::InternalError(absl::StrCat("fork: ", std::strerror(errno)));
  if (pid == 0) {
    prctl(PR_SET_PDEATHSIG, SIGKILL);
    if (getppid() != parent) _exit(126);                 // the parent died before prctl
    if (stdout_fd >= 0) dup2(stdout_fd, STDOUT_FILENO);  // dup2 clears O_CLOEXEC on the copy
    execve(argv[0], argv.data(), envp.data());
    _exit(127);
  }
  return std::unique_ptr<ChildProcess>(new ChildProcess(pid));
}

bool ChildProcess::running() {
  int status = 0;
  if (!reaped_ && waitpid(pid_, &status, WNOHANG) == pid_) reaped_ = true;
  return !reaped_;
}

ChildProcess::~ChildProcess() {
  if (reaped_) return;
  int status = 0;
  kill(pid_, SIGTERM);
  if (!WaitFor(pid_, std::chrono::seconds(15), &status)) {
    kill(pid_, SIGKILL);
    waitpid(pid_, &status, 0);
  }
}

absl::StatusOr<std::unique_ptr<ServerProcess>> ServerProcess::Start(
    const std::string& binary, const std::string& data_dir, const std::vector<std::string>& extra) {
  if (access(binary.c_str(), X_OK) != 0) {
    return absl::NotFoundError(absl::StrCat("actopo-server not found at ", binary,
                                            " (build the server or set ACTOPO_SERVER_BIN)"));
  }
  std::string gate_dir = (std::filesystem::temp_directory_path() / "actopo_gate_XXXXXX").string();
  if (mkdtemp(gate_dir.data()) == nullptr) {
    return absl::InternalError(absl::StrCat("mkdtemp: ", std::strerror(errno)));
  }
  std::vector<std::string> args = {binary, "--host",          "127.0.0.1", "--port",
                                   "0",    "--data-dir",      data_dir,    "--grace-s",
                                   "2",    "--test-gate-dir", gate_dir};
  args.insert(args.end(), extra.begin(), extra.end());
  int fds[2];
  if (pipe2(fds, O_CLOEXEC) != 0) {
    return absl::InternalError(absl::StrCat("pipe: ", std::strerror(errno)));
  }
  absl::StatusOr<std::unique_ptr<ChildProcess>> child = ChildProcess::Start(args, fds[1]);
  close(fds[1]);
  if (!child.ok()) {
    std::error_code ec;
    std::filesystem::remove_all(gate_dir, ec);
    close(fds[0]);
    return child.status();
  }
  std::unique_ptr<ServerProcess> server(new ServerProcess(*std::move(child), fds[0]));
  server->gate_dir_ = gate_dir;
  std::string line;
  if (!ReadLine(fds[0], std::chrono::seconds(60), line) ||
      line.rfind(std::string(kListening), 0) != 0) {
    return absl::UnavailableError(absl::StrCat(binary, " did not print '", std::string(kListening),
                                               "HOST:PORT' (first line: '", line,
                                               "'); its stderr is above"));
  }
  server->target_ = line.substr(kListening.size());
  server->port_ = std::stoi(server->target_.substr(server->target_.rfind(':') + 1));
  server->drain_ = std::thread([fd = fds[0]] {
    char buffer[4096];
    while (read(fd, buffer, sizeof buffer) > 0) {
    }
  });
  return server;
}

ServerProcess::~ServerProcess() {
  child_.reset();                        // stops the child
  if (drain_.joinable()) drain_.join();  // EOF once the child is gone
  close(out_);
  std::error_code ec;
  std::filesystem::remove_all(gate_dir_, ec);
}

std::unique_ptr<WorkHold> ServerProcess::Hold(const std::string& work) const {
  std::string name = work;
  std::replace(name.begin(), name.end(), '/', '.');
  const std::string file = (std::filesystem::path(gate_dir_) / name).string();
  std::ofstream(file).close();
  return std::unique_ptr<WorkHold>(new WorkHold(file));
}

}  // namespace actopo::client::testing
