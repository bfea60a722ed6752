#include "server/io/isolated_reader.h"

#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <spawn.h>
#include <sys/mman.h>
#include <sys/prctl.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <fstream>
#include <string_view>
#include <type_traits>
#include <vector>

#include "absl/strings/match.h"
#include "absl/strings/str_cat.h"
#include "server/core/status_macros.h"
#include "server/io/vtk_reader.h"

extern char** environ;

namespace actopo::io {
namespace {

// The pipe carries frames: one kind byte, then its payload.
//   'p'  progress: a double in [0, 1]
//   'e'  error: int32 status code, uint32 length, message
//   'm'  mesh: int64 vertices, int64 tetrahedra, int32 fields, per field (uint32 length, name,
//        uint8 is_integer, int8 source_bytes).
// The arrays go through a memory file (memfd) the parent passes as descriptor kArraysFd and the
// child fills before it sends 'm': the points (3 doubles per vertex), the tetrahedra (4 int32
// each), each field's values (a double per vertex), back to back. Through the pipe they would
// cost a wake-up per pipe buffer on both sides; through the memory file, one copy in and one
// out.
constexpr char kProgress = 'p', kError = 'e', kMesh = 'm';
constexpr int kArraysFd = 3;

#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
constexpr bool kSanitized = true;  // their shadow memory counts as data: no limit then
#elif defined(__has_feature)
#if __has_feature(address_sanitizer) || __has_feature(thread_sanitizer)
constexpr bool kSanitized = true;
#else
constexpr bool kSanitized = false;
#endif
#else
constexpr bool kSanitized = false;
#endif

// ---- The child's side.

class FrameWriter {
 public:
  explicit FrameWriter(int fd) : fd_(fd) {}
  bool ok() const { return ok_; }

  void Bytes(const void* data, size_t n) {
    const char* p = static_cast<const char*>(data);
    while (ok_ && n > 0) {
      const ssize_t w = ::write(fd_, p, n);
      if (w < 0 && errno == EINTR) continue;
      if (w <= 0) {
        ok_ = false;  // the parent is gone: nothing left to do
        return;
      }
      p += w;
      n -= size_t(w);
    }
  }
  template <typename T>
  void Value(T v) {
    Bytes(&v, sizeof v);
  }
  void String(std::string_view s) {
    Value(uint32_t(s.size()));
    Bytes(s.data(), s.size());
  }

 private:
  int fd_;
  bool ok_ = true;
};

int64_t DataSegmentBytes() {
  std::ifstream status("/proc/self/status");
  std::string line;
  while (std::getline(status, line)) {
    if (absl::StartsWith(line, "VmData:")) return int64_t(std::atoll(line.c_str() + 7)) << 10;
  }
  return 0;
}

// ---- The parent's side.

const char* SignalName(int sig) {
  switch (sig) {
    case SIGSEGV: return "SIGSEGV";
    case SIGBUS: return "SIGBUS";
    case SIGFPE: return "SIGFPE";
    case SIGILL: return "SIGILL";
    case SIGABRT: return "SIGABRT";
    case SIGKILL: return "SIGKILL";
    default: return "a signal";
  }
}

// Reads the child's stdout exactly as asked, keeping the tail of its stderr for the error
// message, and gives up (killing the child) once `progress` says stop.
class ChildPipes {
 public:
  ChildPipes(int out, int err, const Progress& progress)
      : out_(out), err_(err), progress_(progress) {}

  // False at end of stream (the child exited or crashed) or when stopped; see stopped().
  bool Read(void* data, size_t n) {
    char* p = static_cast<char*>(data);
    while (n > 0) {
      if (progress_.stopped()) {
        stopped_ = true;
        return false;
      }
      pollfd fds[2] = {{out_, POLLIN, 0}, {err_, POLLIN, 0}};
      const int ready = ::poll(fds, err_open_ ? 2 : 1, 50);
      if (ready < 0 && errno != EINTR) return false;
      if (ready <= 0) continue;
      if (err_open_ && fds[1].revents && !DrainStderr()) err_open_ = false;
      if (fds[0].revents == 0) continue;
      const ssize_t r = ::read(out_, p, n);
      if (r < 0 && (errno == EINTR || errno == EAGAIN)) continue;
      if (r <= 0) return false;
      p += r;
      n -= size_t(r);
    }
    return true;
  }
  template <typename T>
  bool Value(T& v) {
    return Read(&v, sizeof v);
  }
  bool String(std::string& s, uint32_t max_length) {
    uint32_t length = 0;
    if (!Value(length) || length > max_length) return false;
    s.resize(length);
    return Read(s.data(), length);
  }
  bool stopped() const { return stopped_; }
  // The last lines the child wrote to stderr, read to the end.
  std::string StderrTail() {
    while (err_open_ && DrainStderr()) {
    }
    err_open_ = false;
    // VTK colours its log lines: keep the text, one line per "; ".
    std::string tail;
    for (size_t i = 0; i < stderr_.size(); ++i) {
      if (stderr_[i] == '\x1b') {
        while (i < stderr_.size() && stderr_[i] != 'm') ++i;
      } else if (stderr_[i] == '\n') {
        if (!tail.empty() && i + 1 < stderr_.size()) tail += "; ";
      } else {
        tail += stderr_[i];
      }
    }
    while (!tail.empty() && (tail.back() == ' ' || tail.back() == ';')) tail.pop_back();
    return tail.size() > 400 ? "..." + tail.substr(tail.size() - 400) : tail;
  }

 private:
  bool DrainStderr() {
    char chunk[4096];
    const ssize_t r = ::read(err_, chunk, sizeof chunk);
    if (r <= 0) return false;
    stderr_.append(chunk, size_t(r));
    if (stderr_.size() > 2048) stderr_.erase(0, stderr_.size() - 2048);
    return true;
  }

  int out_, err_;
  const Progress& progress_;
  bool err_open_ = true;
  bool stopped_ = false;
  std::string stderr_;
};

struct Fd {
  int fd = -1;
  ~Fd() { Close(); }
  void Close() {
    if (fd >= 0) ::close(fd);
    fd = -1;
  }
};

// A started child, killed and reaped if still running when this goes.
class Child {
 public:
  ~Child() {
    if (pid_ > 0) {
      ::kill(pid_, SIGKILL);
      Wait();
    }
  }
  absl::Status Spawn(const std::string& reader, const std::vector<std::string>& args, int out_write,
                     int err_write, int arrays) {
    posix_spawn_file_actions_t actions;
    posix_spawn_file_actions_init(&actions);
    posix_spawn_file_actions_adddup2(&actions, out_write, STDOUT_FILENO);
    posix_spawn_file_actions_adddup2(&actions, err_write, STDERR_FILENO);
    posix_spawn_file_actions_adddup2(&actions, arrays, kArraysFd);
    posix_spawn_file_actions_addopen(&actions, STDIN_FILENO, "/dev/null", O_RDONLY, 0);
    // The server blocks SIGTERM and SIGINT in every thread and children inherit the mask.
    posix_spawnattr_t attr;
    posix_spawnattr_init(&attr);
    sigset_t none, defaults;
    sigemptyset(&none);
    sigemptyset(&defaults);
    for (int sig : {SIGPIPE, SIGTERM, SIGINT}) sigaddset(&defaults, sig);
    posix_spawnattr_setsigmask(&attr, &none);
    posix_spawnattr_setsigdefault(&attr, &defaults);
    posix_spawnattr_setflags(&attr, POSIX_SPAWN_SETSIGMASK | POSIX_SPAWN_SETSIGDEF);
    std::vector<char*> argv;
    argv.push_back(const_cast<char*>(reader.c_str()));
    for (const std::string& a : args) argv.push_back(const_cast<char*>(a.c_str()));
    argv.push_back(nullptr);
    const int error = posix_spawn(&pid_, reader.c_str(), &actions, &attr, argv.data(), environ);
    posix_spawn_file_actions_destroy(&actions);
    posix_spawnattr_destroy(&attr);
    if (error != 0) {
      pid_ = 0;
      return absl::InternalError(
          absl::StrCat("cannot start the mesh reader '", reader, "': ", std::strerror(error)));
    }
    return absl::OkStatus();
  }
  // The wait status; kills first when `kill`.
  int Wait(bool kill = false) {
    if (pid_ <= 0) return status_;
    if (kill) ::kill(pid_, SIGKILL);
    while (::waitpid(pid_, &status_, 0) < 0 && errno == EINTR) {
    }
    pid_ = 0;
    return status_;
  }

 private:
  pid_t pid_ = 0;
  int status_ = 0;
};

// Why the child ended without an answer.
absl::Status ChildFailure(const std::string& path, int status, const std::string& stderr_tail) {
  const std::string detail = stderr_tail.empty() ? "" : absl::StrCat(" (", stderr_tail, ")");
  if (WIFSIGNALED(status)) {
    const int sig = WTERMSIG(status);
    if (sig == SIGKILL) {
      return absl::ResourceExhaustedError(absl::StrCat(
          path, ": the mesh reader was killed while reading it, most likely out of memory",
          detail));
    }
    return absl::InvalidArgumentError(absl::StrCat(path, ": VTK's reader crashed on this file (",
                                                   SignalName(sig), ", signal ", sig,
                                                   "); the file is corrupt or truncated", detail));
  }
  // A sanitizer build reports a crash and exits instead of dying by the signal.
  return absl::InvalidArgumentError(absl::StrCat(path, ": VTK's reader crashed on this file (exit ",
                                                 WIFEXITED(status) ? WEXITSTATUS(status) : -1,
                                                 "); the file is corrupt or truncated", detail));
}

}  // namespace

bool IsolatedReadLimitsMemory() { return !kSanitized; }

int ServeMeshRead(const std::string& path, int64_t memory_limit_bytes, int fd, int arrays_fd) {
  ::prctl(PR_SET_PDEATHSIG, SIGKILL);  // never outlive the server
  FrameWriter out(fd);
  if (memory_limit_bytes > 0 && !kSanitized) {
    const rlim_t limit = rlim_t(DataSegmentBytes() + memory_limit_bytes);
    const rlimit data{limit, limit};
    ::setrlimit(RLIMIT_DATA, &data);
  }
  const rlimit no_core{0, 0};
  ::setrlimit(RLIMIT_CORE, &no_core);

  // ReadMesh turns VTK's exceptions, std::bad_alloc at the limit included, into errors.
  const Progress progress(Progress::Options{.report = [&out](std::string_view, double fraction) {
    out.Value(kProgress);
    out.Value(fraction);
  }});
  absl::StatusOr<Mesh> mesh = ReadMesh(path, {}, progress);
  if (!mesh.ok()) {
    absl::Status status = mesh.status();
    // VTK reports a failed allocation as a read error; under a limit that is the limit.
    if (memory_limit_bytes > 0 && absl::StrContains(status.message(), "allocat")) {
      status = absl::ResourceExhaustedError(
          absl::StrCat(status.message(), " (reading is limited to ", memory_limit_bytes >> 20,
                       " MiB by the header's counts; the file announces less than it holds)"));
    }
    out.Value(kError);
    out.Value(int32_t(status.code()));
    out.String(std::string(status.message()));
    return 1;
  }
  // The arrays first, then the frame that says they are there.
  FrameWriter arrays(arrays_fd);
  const auto put = [&arrays](const auto& v) { arrays.Bytes(v.data(), v.size() * sizeof(v[0])); };
  put(mesh->points);
  put(mesh->tetrahedra);
  for (const PointField& f : mesh->point_fields) put(f.values);
  if (!arrays.ok()) {
    out.Value(kError);
    out.Value(int32_t(absl::StatusCode::kResourceExhausted));
    out.String(absl::StrCat(
        path, ": the mesh reader could not hand over the arrays: ", std::strerror(errno)));
    return 1;
  }
  out.Value(kMesh);
  out.Value(int64_t(mesh->num_vertices()));
  out.Value(int64_t(mesh->num_tetrahedra()));
  out.Value(int32_t(mesh->point_fields.size()));
  for (const PointField& f : mesh->point_fields) {
    out.String(f.name);
    out.Value(uint8_t(f.is_integer));
    out.Value(f.source_bytes);
    out.Value(uint8_t(f.time.has_value()));
    out.Value(f.time.value_or(0.0));
  }
  return out.ok() ? 0 : 1;
}

namespace {

// The arrays the child wrote into the memory file `fd`, in order: points, tetrahedra, each
// field's values. False when the file is shorter than `shape` says.
bool ReadArrays(int fd, const MeshShape& shape, Mesh& mesh) {
  int64_t offset = 0;
  // Through a small buffer, so that the arrays' pages are written once (resize() would zero
  // them first).
  std::vector<char> chunk(size_t(1) << 20);
  const auto take = [&](auto& v, int64_t count) {
    using T = std::decay_t<decltype(v[0])>;
    v.clear();
    v.reserve(size_t(count));
    for (int64_t left = count * int64_t(sizeof(T)); left > 0;) {
      const size_t want = size_t(std::min<int64_t>(left, int64_t(chunk.size())));
      const ssize_t r = ::pread(fd, chunk.data(), want, offset);
      if (r < 0 && errno == EINTR) continue;
      if (r <= 0 || size_t(r) % sizeof(T) != 0) return false;
      const T* begin = reinterpret_cast<const T*>(chunk.data());
      v.insert(v.end(), begin, begin + size_t(r) / sizeof(T));
      offset += r;
      left -= r;
    }
    return true;
  };
  bool complete =
      take(mesh.points, 3 * shape.vertices) && take(mesh.tetrahedra, 4 * shape.tetrahedra);
  for (PointField& f : mesh.point_fields) complete = complete && take(f.values, shape.vertices);
  return complete;
}

}  // namespace

absl::StatusOr<Mesh> ReadMeshIsolated(const std::string& path, const IsolatedReadOptions& options,
                                      const Progress& progress) {
  RETURN_IF_ERROR(progress.status("read"));
  Fd out_read, out_write, err_read, err_write;
  int fds[2];
  if (::pipe2(fds, O_CLOEXEC) != 0) return absl::InternalError("mesh reader: pipe failed");
  out_read.fd = fds[0], out_write.fd = fds[1];
  if (::pipe2(fds, O_CLOEXEC) != 0) return absl::InternalError("mesh reader: pipe failed");
  err_read.fd = fds[0], err_write.fd = fds[1];
  Fd arrays;
  arrays.fd = ::memfd_create("actopo-mesh-arrays", MFD_CLOEXEC);
  if (arrays.fd < 0) {
    return absl::InternalError(absl::StrCat("mesh reader: memfd_create: ", std::strerror(errno)));
  }

  Child child;
  RETURN_IF_ERROR(child.Spawn(options.reader, {path, absl::StrCat(options.memory_limit_bytes)},
                              out_write.fd, err_write.fd, arrays.fd));
  out_write.Close();
  err_write.Close();

  ChildPipes in(out_read.fd, err_read.fd, progress);
  const auto failed = [&]() -> absl::Status {
    if (in.stopped()) {
      child.Wait(/*kill=*/true);
      return progress.status("read");
    }
    const std::string tail = in.StderrTail();
    return ChildFailure(path, child.Wait(), tail);
  };
  constexpr uint32_t kMaxText = 1 << 16;
  for (;;) {
    char kind = 0;
    if (!in.Value(kind)) return failed();
    if (kind == kProgress) {
      double fraction = 0;
      if (!in.Value(fraction)) return failed();
      if (absl::Status s = progress.Update("read", fraction); !s.ok()) {
        child.Wait(/*kill=*/true);
        return s;
      }
      continue;
    }
    if (kind == kError) {
      int32_t code = 0;
      std::string message;
      if (!in.Value(code) || !in.String(message, kMaxText)) return failed();
      child.Wait();
      if (code <= 0 || code > int32_t(absl::StatusCode::kUnauthenticated)) {
        code = int32_t(absl::StatusCode::kInternal);
      }
      return absl::Status(absl::StatusCode(code), message);
    }
    if (kind != kMesh) {
      child.Wait(/*kill=*/true);
      return absl::InternalError(absl::StrCat(path, ": the mesh reader sent an unknown frame"));
    }
    break;
  }
  MeshShape shape;
  int32_t fields = 0;
  if (!in.Value(shape.vertices) || !in.Value(shape.tetrahedra) || !in.Value(fields)) {
    return failed();
  }
  if (shape.vertices < 0 || shape.tetrahedra < 0 || fields < 0 || fields > 4096 ||
      shape.vertices > int64_t(1) << 40 || shape.tetrahedra > int64_t(1) << 40) {
    child.Wait(/*kill=*/true);
    return absl::InternalError(absl::StrCat(path, ": the mesh reader sent impossible counts"));
  }
  shape.point_fields = fields;
  if (options.admit) {
    if (absl::Status s = options.admit(shape); !s.ok()) {
      child.Wait(/*kill=*/true);
      return s;
    }
  }
  Mesh mesh;
  mesh.point_fields.resize(size_t(fields));
  for (PointField& f : mesh.point_fields) {
    uint8_t is_integer = 0, has_time = 0;
    double time = 0;
    if (!in.String(f.name, kMaxText) || !in.Value(is_integer) || !in.Value(f.source_bytes) ||
        !in.Value(has_time) || !in.Value(time)) {
      return failed();
    }
    f.is_integer = is_integer != 0;
    if (has_time != 0) f.time = time;
  }
  // The child has written the arrays and is exiting; they are read back from the memory file.
  const bool complete = ReadArrays(arrays.fd, shape, mesh);
  if (!complete) {
    child.Wait(/*kill=*/true);
    return absl::InternalError(
        absl::StrCat(path, ": the mesh reader's arrays are shorter than its counts"));
  }
  const int status = child.Wait();
  if (!WIFEXITED(status) || WEXITSTATUS(status) != 0) {
    return ChildFailure(path, status, in.StderrTail());
  }
  return mesh;
}

}  // namespace actopo::io
