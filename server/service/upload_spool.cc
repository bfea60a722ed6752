#include "server/service/upload_spool.h"

#include <fcntl.h>
#include <sys/file.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <csignal>
#include <cstring>

#include "absl/strings/ascii.h"
#include "absl/strings/match.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_split.h"
#include "server/algorithms/digest.h"
#include "server/core/status_macros.h"
#include "server/service/ids.h"

namespace actopo::service {

// One upload: its files, what the server holds of each, and each file's running digest. The
// spool's mutex guards `received`, `checked`, `last_write`, `writing`, `generation` and
// `dropped`; `write_mu` (taken before the spool's) is held by an append from start to end and
// by a writer taking the upload over, so the bytes on disk, the digests and `received` agree.
struct UploadSpool::Writer::Upload {
  std::string id;
  std::filesystem::path dir;
  std::vector<FileSpec> files;
  std::vector<int64_t> received;
  std::vector<std::unique_ptr<Sha256>> digests;  // per file, fed as its bytes are written
  std::vector<bool> checked;                     // per file: complete, its digest right
  Reservation reservation;
  std::chrono::steady_clock::time_point last_write;
  bool writing = false;
  uint64_t generation = 0;  // the writer that may append: the latest
  bool dropped = false;     // deleted, expired or failed while a writer held it
  Mutex write_mu;
};

namespace {

std::string Errno() { return std::strerror(errno); }

// A path the client names a file by: relative, '/'-separated, no empty, '.' or '..' part.
absl::Status CheckRelativePath(const std::string& path, const std::string& field) {
  if (path.empty()) return absl::InvalidArgumentError(absl::StrCat(field, ": empty"));
  if (path.front() == '/' || absl::StrContains(path, '\0') || absl::StrContains(path, '\\')) {
    return absl::InvalidArgumentError(
        absl::StrCat(field, ": '", path, "' is not a relative path with '/' between its parts"));
  }
  for (absl::string_view part : absl::StrSplit(path, '/')) {
    if (part.empty() || part == "." || part == "..") {
      return absl::InvalidArgumentError(
          absl::StrCat(field, ": '", path, "' has a part '", std::string(part),
                       "' (an upload's files stay inside its folder)"));
    }
  }
  return absl::OkStatus();
}

// `digest` made again from the first `bytes` bytes of `path`.
absl::Status Rehash(const std::filesystem::path& path, int64_t bytes,
                    std::unique_ptr<Sha256>& digest) {
  digest = std::make_unique<Sha256>();
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) return absl::InternalError(absl::StrCat("reading '", path.string(), "': ", Errno()));
  std::string buffer(size_t(1) << 20, '\0');
  for (int64_t done = 0; done < bytes;) {
    const ssize_t n =
        ::read(fd, buffer.data(), size_t(std::min<int64_t>(int64_t(buffer.size()), bytes - done)));
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) {
      ::close(fd);
      return absl::InternalError(absl::StrCat("reading '", path.string(), "' again"));
    }
    digest->Update(std::string_view(buffer.data(), size_t(n)));
    done += n;
  }
  ::close(fd);
  return absl::OkStatus();
}

bool IsSha256Hex(const std::string& s) {
  if (s.size() != 64) return false;
  for (char c : s) {
    if (!absl::ascii_isdigit(c) && (c < 'a' || c > 'f')) return false;
  }
  return true;
}

}  // namespace

UploadSpool::Writer::Writer(UploadSpool* spool, std::shared_ptr<Upload> upload, int file, int fd,
                            uint64_t generation)
    : spool_(spool), upload_(std::move(upload)), file_(file), fd_(fd), generation_(generation) {}

UploadSpool::Writer::Writer(Writer&& o) noexcept
    : spool_(o.spool_),
      upload_(std::move(o.upload_)),
      file_(o.file_),
      fd_(std::exchange(o.fd_, -1)),
      generation_(o.generation_) {}

UploadSpool::Writer::~Writer() {
  if (fd_ >= 0) ::close(fd_);
  if (upload_ == nullptr) return;
  MutexLock lock(spool_->mu_);
  if (upload_->generation != generation_) return;  // taken over: the newer writer has it
  upload_->writing = false;
  upload_->last_write = std::chrono::steady_clock::now();
}

int64_t UploadSpool::Writer::received() const {
  MutexLock lock(spool_->mu_);
  return upload_->received[file_];
}

absl::Status UploadSpool::Writer::Append(std::string_view bytes) {
  Upload& u = *upload_;
  const FileSpec& spec = u.files[file_];
  MutexLock write_lock(u.write_mu);
  int64_t held = 0;
  {
    MutexLock lock(spool_->mu_);
    if (u.dropped) {
      return absl::NotFoundError(absl::StrCat("upload_id: '", u.id, "' was dropped"));
    }
    if (u.generation != generation_) {
      return absl::AbortedError(
          absl::StrCat("upload '", u.id, "' was taken over by a newer WriteUpload call"));
    }
    held = u.received[file_];
  }
  if (int64_t(bytes.size()) > spec.size - held) {
    spool_->DropNow(u.id);
    return absl::InvalidArgumentError(absl::StrCat(
        "files[", file_, "] '", spec.path, "': more than the ", spec.size, " bytes announced (",
        held + int64_t(bytes.size()), " sent); the upload is dropped"));
  }
  for (size_t done = 0; done < bytes.size();) {
    const ssize_t n = ::write(fd_, bytes.data() + done, bytes.size() - done);
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) {
      const std::string why = Errno();
      spool_->DropNow(u.id);
      return absl::ResourceExhaustedError(
          absl::StrCat("writing '", spec.path, "' to the server's spool: ", why));
    }
    done += size_t(n);
  }
  u.digests[file_]->Update(bytes);  // the writer's alone while it holds the upload
  held += int64_t(bytes.size());
  const bool last = held == spec.size;
  if (last) {
    const std::string digest = u.digests[file_]->HexDigest();
    if (digest != spec.sha256) {
      spool_->DropNow(u.id);
      return absl::DataLossError(
          absl::StrCat("files[", file_, "] '", spec.path, "': the bytes received hash to ", digest,
                       ", not the announced ", spec.sha256, "; the upload is dropped"));
    }
  }
  MutexLock lock(spool_->mu_);
  u.received[file_] = held;
  if (last) u.checked[file_] = true;
  return absl::OkStatus();
}

UploadSpool::Taken::Taken(std::filesystem::path dir, std::string main, Reservation reservation)
    : dir_(std::move(dir)), main_(std::move(main)), reservation_(std::move(reservation)) {}

UploadSpool::Taken::Taken(Taken&& o) noexcept
    : dir_(std::move(o.dir_)), main_(std::move(o.main_)), reservation_(std::move(o.reservation_)) {
  o.dir_.clear();
}

UploadSpool::Taken::~Taken() {
  std::error_code ec;
  if (!dir_.empty()) std::filesystem::remove_all(dir_, ec);
}

UploadSpool::UploadSpool(const UploadSpoolOptions& options)
    : options_(options),
      budget_(options.budget_bytes, "upload budget",
              "finish or delete uploads, or raise --upload-budget-mib") {}

namespace {

// Removes the uploads' folders (named upload-...) in `dir`, nothing else a user keeps there.
void RemoveUploadFolders(const std::filesystem::path& dir) {
  std::error_code ec;
  for (const auto& entry : std::filesystem::directory_iterator(dir, ec)) {
    if (entry.path().filename().string().rfind("upload-", 0) == 0) {
      std::filesystem::remove_all(entry.path(), ec);
    }
  }
}

}  // namespace

namespace {

// Opens `path` (creating it when asked) and locks it without waiting: the descriptor, -1 with
// errno EWOULDBLOCK when another process holds the lock, -1 with errno set on other failures.
int OpenLocked(const std::filesystem::path& path, bool create) {
  const int fd = ::open(path.c_str(), O_RDWR | O_CLOEXEC | (create ? O_CREAT : 0), 0600);
  if (fd < 0) return -1;
  if (::flock(fd, LOCK_EX | LOCK_NB) != 0) {
    const int error = errno;
    ::close(fd);
    errno = error;
    return -1;
  }
  return fd;
}

// Whether `name` is PREFIX<pid>-... with a pid no process has.
bool NamesAGoneProcess(std::string_view name, std::string_view prefix) {
  const std::string_view rest = name.substr(prefix.size());
  int pid = 0;
  const auto [end, error] = std::from_chars(rest.data(), rest.data() + rest.size(), pid);
  if (error != std::errc() || end == rest.data() || end == rest.data() + rest.size() ||
      *end != '-' || pid <= 0) {
    return false;
  }
  return ::kill(pid, 0) != 0 && errno == ESRCH;
}

}  // namespace

absl::StatusOr<std::unique_ptr<UploadSpool>> UploadSpool::Open(const UploadSpoolOptions& options) {
  std::error_code ec;
  const bool made = std::filesystem::create_directories(options.dir, ec);
  if (ec) {
    return absl::FailedPreconditionError(
        absl::StrCat("upload folder '", options.dir.string(), "': ", ec.message()));
  }
  const std::filesystem::path lock_path = options.dir / kLockFile;
  const int lock_fd = OpenLocked(lock_path, /*create=*/true);
  if (lock_fd < 0) {
    return absl::FailedPreconditionError(absl::StrCat(
        "upload folder '", options.dir.string(), "': ",
        errno == EWOULDBLOCK ? "in use by another running server (it holds " : "cannot lock (",
        lock_path.filename().string(),
        errno == EWOULDBLOCK ? ")" : "): ", errno == EWOULDBLOCK ? "" : std::strerror(errno)));
  }
  RemoveUploadFolders(options.dir);  // what an earlier run left is no one's now
  std::unique_ptr<UploadSpool> spool(new UploadSpool(options));
  spool->made_dir_ = made;
  spool->lock_fd_ = lock_fd;
  spool->reaper_ = std::thread([s = spool.get()] { s->ReapExpired(); });
  return spool;
}

UploadSpool::~UploadSpool() {
  {
    MutexLock lock(mu_);
    stopping_ = true;
  }
  reaper_cv_.SignalAll();
  reaper_.join();
  RemoveUploadFolders(options_.dir);
  std::error_code ec;
  std::filesystem::remove(options_.dir / kLockFile, ec);  // still held: no one takes it between
  ::close(lock_fd_);
  if (made_dir_) std::filesystem::remove(options_.dir, ec);  // only if empty
}

int UploadSpool::RemoveAbandoned(const std::filesystem::path& parent, std::string_view prefix) {
  // A server makes its folder, then its lock file, then locks it: between the two a folder of a
  // live process holds an unlocked (or no) lock file for a moment, so the process id decides
  // there, and an unlocked lock file only once it is older than a server's start.
  constexpr auto kStarting = std::chrono::seconds(60);
  int removed = 0;
  std::error_code ec;
  for (const auto& entry : std::filesystem::directory_iterator(parent, ec)) {
    const std::string name = entry.path().filename().string();
    if (name.rfind(prefix, 0) != 0 || !entry.is_directory(ec)) continue;
    const std::filesystem::path lock_path = entry.path() / kLockFile;
    const int fd = OpenLocked(lock_path, /*create=*/false);
    const int error = fd < 0 ? errno : 0;
    if (fd >= 0) ::close(fd);
    if (error == EWOULDBLOCK) continue;  // a running server's
    std::error_code age_ec;
    const auto written = std::filesystem::last_write_time(lock_path, age_ec);
    const bool stale_lock =
        fd >= 0 && !age_ec && std::filesystem::file_time_type::clock::now() - written > kStarting;
    if (!NamesAGoneProcess(name, prefix) && !stale_lock) continue;
    if (std::filesystem::remove_all(entry.path(), ec) > 0 && !ec) ++removed;
  }
  return removed;
}

int UploadSpool::size() const {
  MutexLock lock(mu_);
  return int(uploads_.size());
}

absl::StatusOr<std::string> UploadSpool::Create(std::vector<FileSpec> files) {
  if (files.empty()) return absl::InvalidArgumentError("files: none");
  int64_t total = 0;
  for (size_t k = 0; k < files.size(); ++k) {
    const std::string field = absl::StrCat("files[", k, "]");
    RETURN_IF_ERROR(CheckRelativePath(files[k].path, field + ".path"));
    if (files[k].size < 0) {
      return absl::InvalidArgumentError(absl::StrCat(field, ".size: ", files[k].size));
    }
    if (!IsSha256Hex(files[k].sha256)) {
      return absl::InvalidArgumentError(
          absl::StrCat(field, ".sha256: '", files[k].sha256, "' is not 64 lowercase hex digits"));
    }
    for (size_t j = 0; j < k; ++j) {
      if (files[j].path == files[k].path) {
        return absl::InvalidArgumentError(
            absl::StrCat(field, ".path: '", files[k].path, "' is files[", j, "] too"));
      }
    }
    total += files[k].size;
  }
  auto u = std::make_shared<Writer::Upload>();
  u->id = NewId("upload");
  u->dir = options_.dir / u->id;
  u->reservation = Reservation(&budget_);
  {
    MutexLock lock(mu_);
    if (int(uploads_.size()) >= options_.max_uploads) {
      return absl::ResourceExhaustedError(absl::StrCat(
          "the server holds ", uploads_.size(), " uploads, its limit; finish or delete one"));
    }
    RETURN_IF_ERROR(u->reservation.Resize(
        total, absl::StrCat("an upload of ", total, " bytes (", files.size(), " files)")));
  }
  std::error_code ec;
  for (const FileSpec& f : files) {
    const std::filesystem::path path = u->dir / f.path;
    std::filesystem::create_directories(path.parent_path(), ec);
    const int fd = ::open(path.c_str(), O_CREAT | O_TRUNC | O_WRONLY | O_CLOEXEC, 0600);
    if (fd < 0) {
      const std::string why = Errno();
      std::filesystem::remove_all(u->dir, ec);
      return absl::InternalError(absl::StrCat("creating '", f.path, "' in the spool: ", why));
    }
    ::close(fd);
    u->digests.push_back(std::make_unique<Sha256>());
  }
  u->received.assign(files.size(), 0);
  u->checked.assign(files.size(), false);
  // An empty file is complete once created; its digest is checked here.
  for (size_t k = 0; k < files.size(); ++k) {
    if (files[k].size == 0) {
      if (u->digests[k]->HexDigest() != files[k].sha256) {
        std::filesystem::remove_all(u->dir, ec);
        return absl::InvalidArgumentError(
            absl::StrCat("files[", k, "].sha256: not the digest of an empty file (its size is 0)"));
      }
      u->checked[k] = true;
    }
  }
  u->files = std::move(files);
  u->last_write = std::chrono::steady_clock::now();
  MutexLock lock(mu_);
  uploads_[u->id] = u;
  return u->id;
}

absl::StatusOr<std::shared_ptr<UploadSpool::Writer::Upload>> UploadSpool::Find(
    const std::string& id) {
  auto it = uploads_.find(id);
  if (it == uploads_.end()) {
    return absl::NotFoundError(absl::StrCat(
        "upload_id: no upload '", id, "' (never created, finished, deleted, or left alone for ",
        options_.timeout.count(), " s)"));
  }
  return it->second;
}

absl::StatusOr<UploadSpool::Writer> UploadSpool::Write(const std::string& id, int file,
                                                       int64_t offset) {
  std::shared_ptr<Writer::Upload> u;
  {
    MutexLock lock(mu_);
    ASSIGN_OR_RETURN(u, Find(id));
  }
  // An append in progress ends first; a writer still holding the upload (a call whose
  // connection broke without the server noticing yet) is taken over: its next append is refused.
  MutexLock write_lock(u->write_mu);
  uint64_t generation = 0;
  bool rewind = false;
  {
    MutexLock lock(mu_);
    if (u->dropped) return Find(id).status();
    if (file < 0 || file >= int(u->files.size())) {
      return absl::InvalidArgumentError(absl::StrCat("file: ", file, " is not in [0, ",
                                                     u->files.size(), ") for upload '", id, "'"));
    }
    if (offset < 0 || offset > u->received[file]) {
      return absl::FailedPreconditionError(absl::StrCat(
          "offset: ", offset, ", but the server holds ", u->received[file], " bytes of files[",
          file, "] '", u->files[file].path, "'; go on from there"));
    }
    generation = ++u->generation;
    u->writing = true;
    rewind = offset < u->received[file];
    if (rewind) {  // the bytes after `offset` go; the file is neither complete nor checked
      u->received[file] = offset;
      u->checked[file] = false;
    }
  }
  const auto release = [&] {
    MutexLock lock(mu_);
    if (u->generation == generation) u->writing = false;
  };
  const std::filesystem::path path = u->dir / u->files[file].path;
  const int fd = ::open(path.c_str(), O_WRONLY | O_APPEND | O_CLOEXEC);
  if (fd < 0) {
    const std::string why = Errno();
    release();
    return absl::InternalError(absl::StrCat("opening '", path.string(), "': ", why));
  }
  // What a broken earlier stream wrote past its acknowledged bytes goes.
  if (::ftruncate(fd, offset) != 0) {
    const std::string why = Errno();
    ::close(fd);
    release();
    return absl::InternalError(absl::StrCat("truncating '", path.string(), "': ", why));
  }
  if (rewind) {
    // A client going on from fewer bytes than the server holds (it asked while an earlier call
    // was still appending): the digest is made again from the bytes kept.
    if (absl::Status hashed = Rehash(path, offset, u->digests[file]); !hashed.ok()) {
      ::close(fd);
      DropNow(id);
      return hashed;
    }
  }
  return Writer(this, std::move(u), file, fd, generation);
}

absl::StatusOr<UploadSpool::State> UploadSpool::Get(const std::string& id) {
  MutexLock lock(mu_);
  ASSIGN_OR_RETURN(std::shared_ptr<Writer::Upload> u, Find(id));
  State state;
  state.files = u->files;
  state.received = u->received;
  state.complete = std::find(u->checked.begin(), u->checked.end(), false) == u->checked.end();
  const auto idle = std::chrono::steady_clock::now() - u->last_write;
  state.expires_in =
      u->writing
          ? options_.timeout
          : std::max(std::chrono::seconds(0),
                     options_.timeout - std::chrono::duration_cast<std::chrono::seconds>(idle));
  return state;
}

absl::Status UploadSpool::Delete(const std::string& id) {
  MutexLock lock(mu_);
  RETURN_IF_ERROR(Find(id).status());
  Drop(id);
  return absl::OkStatus();
}

absl::StatusOr<UploadSpool::Taken> UploadSpool::Take(const std::string& id) {
  MutexLock lock(mu_);
  ASSIGN_OR_RETURN(std::shared_ptr<Writer::Upload> u, Find(id));
  if (u->writing) {
    return absl::FailedPreconditionError(absl::StrCat("upload '", id, "' is still being written"));
  }
  for (size_t k = 0; k < u->files.size(); ++k) {
    if (!u->checked[k]) {
      return absl::FailedPreconditionError(
          absl::StrCat("upload '", id, "' holds ", u->received[k], " of the ", u->files[k].size,
                       " bytes of files[", k, "] '", u->files[k].path, "'; send the rest first"));
    }
  }
  uploads_.erase(id);
  return Taken(u->dir, u->files[0].path, std::move(u->reservation));
}

void UploadSpool::Drop(const std::string& id) {
  auto it = uploads_.find(id);
  if (it == uploads_.end()) return;
  std::shared_ptr<Writer::Upload> u = std::move(it->second);
  uploads_.erase(it);
  u->dropped = true;
  u->reservation = Reservation();
  std::error_code ec;
  std::filesystem::remove_all(u->dir, ec);  // a writer's open file goes with its last close
}

void UploadSpool::DropNow(const std::string& id) {
  MutexLock lock(mu_);
  Drop(id);
}

void UploadSpool::ReapExpired() {
  MutexLock lock(mu_);
  while (!stopping_) {
    reaper_cv_.WaitFor(mu_, std::chrono::seconds(1));
    const auto now = std::chrono::steady_clock::now();
    std::vector<std::string> expired;
    for (const auto& [id, u] : uploads_) {
      if (!u->writing && now - u->last_write > options_.timeout) expired.push_back(id);
    }
    for (const std::string& id : expired) Drop(id);
  }
}

}  // namespace actopo::service
