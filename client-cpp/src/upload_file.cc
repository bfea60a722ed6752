// Client::UploadFile and the calls under it (CreateUpload, WriteUpload, GetUpload, DeleteUpload,
// LoadUpload): a mesh file, or a .pvd with the files it names, sent as its bytes. The files are
// hashed, then read again a chunk at a time as they are sent, so that memory holds one chunk
// whatever their size; a stream that breaks goes on from the bytes the server holds.
#include <expat.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <condition_variable>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <mutex>
#include <random>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "absl/strings/ascii.h"
#include "absl/strings/str_cat.h"
#include "actopo/client.h"
#include "src/internal/convert.h"
#include "src/internal/core.h"
#include "src/internal/load.h"
#include "src/internal/sha256.h"

namespace actopo::client {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

constexpr size_t kHashBytes = size_t{1} << 20;       // read at a time for the digest
constexpr int64_t kMaxPvdBytes = int64_t{64} << 20;  // a collection is read whole to scan it

std::string Errno() { return std::strerror(errno); }

// ---------------------------------------------------------------------------------------------
// The files: the mesh, and a .pvd's DataSet files.

// A file to send: where it is here and what the upload calls it.
struct LocalFile {
  fs::path local;
  UploadFileInfo info;
};

// The `file` attribute of every DataSet element of a .pvd's text, in order ("" for one without),
// as expat (VTK's XML parser, which the server reads the .pvd with) reads them.
absl::StatusOr<std::vector<std::string>> DataSetFiles(std::string_view xml,
                                                      const std::string& pvd) {
  struct Found {
    std::vector<std::string> files;
  } found;
  const std::unique_ptr<XML_ParserStruct, decltype(&XML_ParserFree)> parser(
      XML_ParserCreate(nullptr), &XML_ParserFree);
  if (parser == nullptr) return absl::ResourceExhaustedError("expat: no parser");
  XML_SetUserData(parser.get(), &found);
  XML_SetStartElementHandler(parser.get(),
                             [](void* data, const XML_Char* name, const XML_Char** attributes) {
                               if (std::string_view(name) != "DataSet") return;
                               std::string file;
                               for (const XML_Char** a = attributes; *a != nullptr; a += 2) {
                                 if (std::string_view(a[0]) == "file") file = a[1];
                               }
                               static_cast<Found*>(data)->files.push_back(std::move(file));
                             });
  if (XML_Parse(parser.get(), xml.data(), int(xml.size()), /*isFinal=*/1) == XML_STATUS_ERROR) {
    return absl::InvalidArgumentError(absl::StrCat(
        pvd, ": not a ParaView collection (", XML_ErrorString(XML_GetErrorCode(parser.get())),
        " at line ", XML_GetCurrentLineNumber(parser.get()), ")"));
  }
  return std::move(found.files);
}

// The path in the upload of DataSet `k`'s file `entry` of the collection `pvd`: relative to the
// .pvd's folder, normalized as the server resolves it, and inside that folder.
absl::StatusOr<std::string> UploadPath(const std::string& entry, size_t k, const std::string& pvd) {
  const auto refuse = [&](const char* why) {
    return absl::InvalidArgumentError(
        absl::StrCat(pvd, ": DataSet ", k, " file '", entry, "' ", why));
  };
  if (entry.empty()) return refuse("is empty (no file attribute); name each DataSet's file");
  if (entry.front() == '/') {
    return refuse(
        "is an absolute path; an upload holds the files under the .pvd's folder, named relative "
        "to it");
  }
  if (entry.find('\\') != std::string::npos) {
    return refuse("has a '\\'; name the files with '/' between the parts of their paths");
  }
  const fs::path normal = fs::path(entry).lexically_normal();
  for (const fs::path& part : normal) {
    if (part == "..") {
      return refuse(
          "leaves the .pvd's folder ('..'); an upload holds only the files under that folder");
    }
  }
  std::string path = normal.generic_string();
  if (path.empty() || path == "." || path.back() == '/')
    return refuse("names a folder, not a file");
  return path;
}

absl::StatusOr<int64_t> SizeOf(const fs::path& file, const std::string& what) {
  std::error_code error;
  if (!fs::is_regular_file(file, error)) {
    return absl::NotFoundError(absl::StrCat(what, ": no file '", file.string(), "'"));
  }
  const uintmax_t size = fs::file_size(file, error);
  if (error) {
    return absl::NotFoundError(
        absl::StrCat(what, ": cannot read '", file.string(), "': ", error.message()));
  }
  return int64_t(size);
}

// The files UploadFile sends for `path`: the mesh, and for a .pvd the DataSet files it names
// (each once), their sizes set, not yet hashed.
absl::StatusOr<std::vector<LocalFile>> FilesOf(const std::string& path) {
  const fs::path main(path);
  const std::string extension = absl::AsciiStrToLower(main.extension().string());
  if (extension != ".vtu" && extension != ".vtk" && extension != ".vti" && extension != ".pvd") {
    return absl::InvalidArgumentError(
        absl::StrCat("path: '", path, "' is not a .vtu, .vtk, .vti or .pvd file"));
  }
  std::vector<LocalFile> files(1);
  files[0].local = main;
  files[0].info.path = main.filename().string();
  ACTOPO_ASSIGN_OR_RETURN(files[0].info.size, SizeOf(main, "path"));
  if (extension != ".pvd") return files;

  if (files[0].info.size > kMaxPvdBytes) {
    return absl::InvalidArgumentError(absl::StrCat("path: '", path, "' has ", files[0].info.size,
                                                   " bytes, more than a ParaView collection (at "
                                                   "most ",
                                                   kMaxPvdBytes >> 20, " MiB)"));
  }
  std::ifstream in(main, std::ios::binary);
  if (!in) return absl::NotFoundError(absl::StrCat("path: cannot open '", path, "': ", Errno()));
  const std::string xml{std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
  if (in.bad()) {
    return absl::DataLossError(absl::StrCat("path: reading '", path, "': ", Errno()));
  }
  ACTOPO_ASSIGN_OR_RETURN(const std::vector<std::string> entries, DataSetFiles(xml, path));
  if (entries.empty()) {
    return absl::InvalidArgumentError(absl::StrCat(path, ": the collection lists no DataSet"));
  }
  std::set<std::string> seen;
  for (size_t k = 0; k < entries.size(); ++k) {
    ACTOPO_ASSIGN_OR_RETURN(std::string relative, UploadPath(entries[k], k, path));
    if (!seen.insert(relative).second) continue;
    LocalFile file;
    file.local = main.parent_path() / relative;
    file.info.path = std::move(relative);
    ACTOPO_ASSIGN_OR_RETURN(
        file.info.size,
        SizeOf(file.local, absl::StrCat(path, ": DataSet ", k, " file '", entries[k], "'")));
    files.push_back(std::move(file));
  }
  return files;
}

// The SHA-256 of the file at `path` and its size, `hashed(n)` called after each n bytes read.
absl::StatusOr<std::pair<std::string, int64_t>> Hash(const fs::path& path,
                                                     const std::function<void(int64_t)>& hashed) {
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    return absl::NotFoundError(absl::StrCat("cannot open '", path.string(), "': ", Errno()));
  }
  internal::Sha256 sha;
  std::vector<char> buffer(kHashBytes);
  int64_t total = 0;
  while (in) {
    in.read(buffer.data(), std::streamsize(buffer.size()));
    const std::streamsize n = in.gcount();
    if (n <= 0) break;
    sha.Update(std::as_bytes(std::span(buffer.data(), size_t(n))));
    total += n;
    if (hashed) hashed(n);
  }
  if (in.bad()) {
    return absl::DataLossError(absl::StrCat("reading '", path.string(), "': ", Errno()));
  }
  ACTOPO_ASSIGN_OR_RETURN(std::string hex, sha.HexDigest());
  return std::pair(std::move(hex), total);
}

absl::Status Changed(const LocalFile& file, int64_t now) {
  return absl::AbortedError(absl::StrCat("'", file.local.string(), "' has ", now,
                                         " bytes, not the ", file.info.size,
                                         " it had when its size was taken: it changed while "
                                         "being uploaded"));
}

// ---------------------------------------------------------------------------------------------
// The calls.

absl::Status CheckPartition(const PartitionOptions& partition) {
  if (partition.block_size < 0) {
    return absl::InvalidArgumentError(
        absl::StrCat("partition.block_size: ", partition.block_size, " is negative"));
  }
  return absl::OkStatus();
}

absl::StatusOr<UploadStatus> Create(const internal::Core& core,
                                    const std::vector<UploadFileInfo>& files) {
  v1::CreateUploadRequest request;
  for (const UploadFileInfo& f : files) {
    v1::UploadFileInfo* file = request.add_files();
    file->set_path(f.path);
    file->set_size(f.size);
    file->set_sha256(f.sha256);
  }
  ACTOPO_ASSIGN_OR_RETURN(
      v1::CreateUploadResponse response,
      core.Unary(&v1::TopologyService::Stub::CreateUpload, request, core.QuickContext()));
  return internal::FromProto(response.upload());
}

absl::StatusOr<UploadStatus> Get(const internal::Core& core, std::string_view upload_id) {
  v1::GetUploadRequest request;
  request.set_upload_id(std::string(upload_id));
  ACTOPO_ASSIGN_OR_RETURN(
      v1::GetUploadResponse response,
      core.Unary(&v1::TopologyService::Stub::GetUpload, request, core.QuickContext()));
  return internal::FromProto(response.upload());
}

// DeleteUpload through `stub`: the client's, or after a stopped WriteUpload one on a connection
// of its own (Core::StubOnOwnConnection), since what that stream had handed to the shared
// connection (up to the server's flow-control window, a few MiB) goes out before anything sent
// after it: seconds on a slow link, never on a stalled one.
absl::Status Delete(const internal::Core& core, v1::TopologyService::Stub& stub,
                    std::string_view upload_id) {
  v1::DeleteUploadRequest request;
  request.set_upload_id(std::string(upload_id));
  v1::DeleteUploadResponse response;
  return internal::FromGrpc(stub.DeleteUpload(core.QuickContext().get(), request, &response));
}

// Puts the `n` bytes of a file from `at` into `chunk` (resized to n).
using Fill = std::function<absl::Status(int64_t at, size_t n, std::string* chunk)>;

// One WriteUpload stream: file `file` of upload `id` from `offset` to `end`, the bytes from
// `fill` a chunk at a time, `sent(n)` after each chunk handed to gRPC. An error of `fill` cancels
// the stream and is returned in `local` as well (it is not the connection's: no resuming).
absl::StatusOr<UploadStatus> Stream(const internal::Core& core, const std::string& id, int32_t file,
                                    int64_t offset, int64_t end, size_t chunk_bytes,
                                    const Fill& fill, const std::function<void(size_t)>& sent,
                                    const internal::OnCancel& on_cancel, absl::Status* local) {
  std::unique_ptr<grpc::ClientContext> context = core.MeshContext();
  grpc::ClientContext* raw = context.get();
  std::shared_ptr<void> registration = on_cancel([raw] { raw->TryCancel(); });
  v1::WriteUploadResponse response;
  std::unique_ptr<grpc::ClientWriter<v1::WriteUploadRequest>> writer =
      core.stub->WriteUpload(raw, &response);
  v1::WriteUploadRequest message;
  v1::WriteUploadStart* start = message.mutable_start();
  start->set_upload_id(id);
  start->set_file(file);
  start->set_offset(offset);
  // A failed write means the call has ended: Finish says why.
  bool open = writer->Write(message);
  std::string* chunk = message.mutable_chunk();
  try {
    for (int64_t at = offset; open && at < end;) {
      const size_t n = size_t(std::min(int64_t(chunk_bytes), end - at));
      if (absl::Status filled = fill(at, n, chunk); !filled.ok()) {
        *local = filled;
        raw->TryCancel();
        open = false;
        break;
      }
      open = writer->Write(message);
      if (open) {
        at += int64_t(n);
        if (sent) sent(n);
      }
    }
  } catch (...) {  // from the progress callback: end the stream before the stack unwinds
    raw->TryCancel();
    writer->Finish();
    throw;
  }
  if (open) writer->WritesDone();
  const grpc::Status status = writer->Finish();
  registration.reset();  // before the context goes
  if (!local->ok()) return *local;
  ACTOPO_RETURN_IF_ERROR(internal::FromGrpc(status));
  return internal::FromProto(response.upload());
}

// ---------------------------------------------------------------------------------------------
// UploadFile.

// Waits between attempts; a cancellation ends the wait at once.
class Pause {
 public:
  explicit Pause(const internal::OnCancel& on_cancel) {
    registration_ = on_cancel([this] {
      std::lock_guard<std::mutex> lock(mu_);
      cancelled_ = true;
      cv_.notify_all();
    });
  }

  // False if cancelled (before or during the wait).
  bool Wait(std::chrono::milliseconds delay) {
    std::unique_lock<std::mutex> lock(mu_);
    return !cv_.wait_for(lock, delay, [this] { return cancelled_; });
  }
  bool cancelled() {
    std::lock_guard<std::mutex> lock(mu_);
    return cancelled_;
  }

 private:
  std::mutex mu_;
  std::condition_variable cv_;
  bool cancelled_ = false;
  std::shared_ptr<void> registration_;  // last: unregistered before the rest goes
};

// Attempt n's wait (n >= 1): 0.2, 0.4, 0.8, 1.6, then 2 s, each +-20%.
std::chrono::milliseconds Backoff(int n) {
  thread_local std::minstd_rand random{std::random_device()()};
  const double base = std::min(2000.0, 200.0 * double(int64_t{1} << std::min(n - 1, 4)));
  return std::chrono::milliseconds(
      int64_t(base * std::uniform_real_distribution<double>(0.8, 1.2)(random)));
}

// The errors after which a stream may go on from what the server holds: a broken connection,
// the deadline of one stream, a stream the server or a proxy ended; for a write also
// FAILED_PRECONDITION, which says the server holds other bytes than the offset sent, or that it
// has not yet noticed that the broken stream before ended.
bool Resumable(const absl::Status& status, bool write) {
  switch (status.code()) {
    case absl::StatusCode::kUnavailable:
    case absl::StatusCode::kDeadlineExceeded:
    case absl::StatusCode::kCancelled: return true;
    case absl::StatusCode::kFailedPrecondition: return write;
    default: return false;
  }
}

int64_t Held(const UploadStatus& upload) {
  int64_t held = 0;
  for (int64_t r : upload.received_bytes) held += r;
  return held;
}

std::string Describe(const std::vector<UploadFileInfo>& files) {
  std::string out;
  for (const UploadFileInfo& f : files) {
    absl::StrAppend(&out, out.empty() ? "" : ", ", "'", f.path, "' (", f.size, " bytes, sha256 ",
                    f.sha256.substr(0, 12), "...)");
  }
  return out;
}

bool SameFiles(const std::vector<UploadFileInfo>& a, const std::vector<UploadFileInfo>& b) {
  return std::equal(a.begin(), a.end(), b.begin(), b.end(), [](const auto& x, const auto& y) {
    return x.path == y.path && x.size == y.size && x.sha256 == y.sha256;
  });
}

// UploadFileOptions::progress, with the figures that carry over from report to report.
class Reporter {
 public:
  explicit Reporter(const std::function<void(const UploadFileProgress&)>& progress)
      : progress_(progress), start_(Clock::now()) {}

  UploadFileProgress state;  // total_bytes, sent_bytes, resumes, upload_id as they are now

  void Report(const std::string& phase, double fraction, int64_t bytes) {
    if (!progress_) return;
    state.phase = phase;
    state.fraction = fraction;
    state.bytes = bytes;
    state.elapsed_seconds = std::chrono::duration<double>(Clock::now() - start_).count();
    progress_(state);
  }
  double Of(int64_t bytes) const {
    return state.total_bytes > 0 ? double(bytes) / double(state.total_bytes) : 1.0;
  }

 private:
  const std::function<void(const UploadFileProgress&)>& progress_;
  Clock::time_point start_;
};

// Deletes the upload when it goes, on a connection of its own (see Delete), unless kept: every
// way out of UploadFile but a success (the load dropped it) or giving up on the connection (the
// server keeps it for a later call).
class DeleteUnlessKept {
 public:
  DeleteUnlessKept(const internal::Core& core, std::string id) : core_(core), id_(std::move(id)) {}
  DeleteUnlessKept(const DeleteUnlessKept&) = delete;
  DeleteUnlessKept& operator=(const DeleteUnlessKept&) = delete;
  ~DeleteUnlessKept() {
    if (!id_.empty()) {
      Delete(core_, *core_.StubOnOwnConnection(), id_).IgnoreError();  // may be gone already
    }
  }
  void Keep() { id_.clear(); }

 private:
  const internal::Core& core_;
  std::string id_;
};

absl::Status CheckOptions(const UploadFileOptions& options) {
  if (options.chunk_bytes == 0) {
    return absl::InvalidArgumentError("options.chunk_bytes: 0; expected a positive size");
  }
  if (options.max_resumes < 0) {
    return absl::InvalidArgumentError(
        absl::StrCat("options.max_resumes: ", options.max_resumes, " is negative"));
  }
  return CheckPartition(options.partition);
}

// What a call that gave up on the connection returns: its last error, and how to go on.
absl::Status GaveUp(const absl::Status& last, const UploadStatus& upload, int64_t total,
                    int resumes, const char* then) {
  return absl::Status(
      last.code(),
      absl::StrCat(last.message(), " (gave up after ", resumes,
                   " resumptions in a row without progress; the server holds ", Held(upload),
                   " of the ", total, " bytes of upload '", upload.upload_id,
                   "' until it is left alone for its upload timeout: ", then, ")"));
}

// Sends what the server lacks of `files`, file after file, going on after a broken stream from
// what it holds (the server lets a new stream take the upload over from one it still thinks
// open). Returns the upload once complete.
absl::StatusOr<UploadStatus> Send(const internal::Core& core, const std::vector<LocalFile>& files,
                                  UploadStatus upload, const UploadFileOptions& options,
                                  const internal::OnCancel& on_cancel, Pause& pause,
                                  Reporter& report, DeleteUnlessKept& guard) {
  const auto cancelled = [] { return absl::CancelledError("upload: cancelled"); };
  int failures = 0;       // attempts in a row without the server gaining a byte
  bool reported = false;  // the position was reported since `upload` last changed
  while (true) {
    if (pause.cancelled()) return cancelled();
    if (upload.received_bytes.size() != files.size()) {
      return absl::DataLossError(absl::StrCat("upload '", upload.upload_id, "': the server says ",
                                              upload.received_bytes.size(), " files, not ",
                                              files.size()));
    }
    size_t k = 0;
    while (k < files.size() && upload.received_bytes[k] >= files[k].info.size) ++k;
    int64_t position = Held(upload);
    if (!reported) report.Report("send", report.Of(position), position);
    reported = true;
    if (k == files.size()) return upload;

    const LocalFile& file = files[k];
    const int64_t offset = upload.received_bytes[k];
    absl::Status local;
    absl::StatusOr<UploadStatus> written;
    std::ifstream in(file.local, std::ios::binary);
    if (!in || !in.seekg(offset)) {
      return absl::NotFoundError(absl::StrCat("cannot read '", file.local.string(), "' from byte ",
                                              offset, ": ", Errno()));
    }
    const Fill fill = [&](int64_t at, size_t n, std::string* chunk) -> absl::Status {
      chunk->resize(n);
      in.read(chunk->data(), std::streamsize(n));
      if (size_t(in.gcount()) != n) return Changed(file, at + in.gcount());
      return absl::OkStatus();
    };
    const auto sent = [&](size_t n) {
      position += int64_t(n);
      report.state.sent_bytes += int64_t(n);
      report.Report("send", report.Of(position), position);
    };
    written = Stream(core, upload.upload_id, int32_t(k), offset, file.info.size,
                     options.chunk_bytes, fill, sent, on_cancel, &local);
    if (written.ok()) {
      if (Held(*written) <= Held(upload)) {  // a finished stream always adds bytes
        return absl::DataLossError(
            absl::StrCat("upload '", upload.upload_id, "': the server accepted the bytes of files[",
                         k, "] from ", offset, " but holds no more of them than before"));
      }
      upload = *std::move(written);
      failures = 0;
      continue;
    }
    if (pause.cancelled()) return cancelled();
    if (!local.ok() || !Resumable(written.status(), /*write=*/true)) return written.status();

    // Ask what the server holds, until it answers or the attempts run out.
    absl::Status broken = written.status();
    reported = false;
    while (true) {
      if (++failures > options.max_resumes) {
        guard.Keep();
        return GaveUp(broken, upload, report.state.total_bytes, failures - 1,
                      "go on with UploadFileOptions::upload_id");
      }
      if (!pause.Wait(Backoff(failures))) return cancelled();
      ++report.state.resumes;
      absl::StatusOr<UploadStatus> held = Get(core, upload.upload_id);
      if (held.ok()) {
        if (Held(*held) > Held(upload)) failures = 0;
        upload = *std::move(held);
        break;
      }
      // NOT_FOUND: the server dropped it (restarted, or the upload timed out).
      if (!Resumable(held.status(), /*write=*/false)) {
        return absl::Status(held.status().code(),
                            absl::StrCat(held.status().message(),
                                         " (after the stream broke: ", broken.ToString(), ")"));
      }
      broken = held.status();
    }
  }
}

absl::StatusOr<MeshInfo> UploadFileImpl(const internal::Core& core, const std::string& path,
                                        const UploadFileOptions& options,
                                        const internal::OnCancel& on_cancel) {
  ACTOPO_RETURN_IF_ERROR(CheckOptions(options));
  Pause pause(on_cancel);
  Reporter report(options.progress);
  ACTOPO_ASSIGN_OR_RETURN(std::vector<LocalFile> files, FilesOf(path));
  for (const LocalFile& f : files) report.state.total_bytes += f.info.size;

  int64_t hashed = 0;
  report.Report("hash", report.Of(0), 0);
  for (LocalFile& f : files) {
    if (pause.cancelled()) return absl::CancelledError("upload: cancelled");
    ACTOPO_ASSIGN_OR_RETURN(const auto digest, Hash(f.local, [&](int64_t n) {
                              hashed += n;
                              report.Report("hash", report.Of(hashed), hashed);
                            }));
    if (digest.second != f.info.size) return Changed(f, digest.second);
    f.info.sha256 = digest.first;
  }
  std::vector<UploadFileInfo> infos;
  for (const LocalFile& f : files) infos.push_back(f.info);

  UploadStatus upload;
  if (options.upload_id.empty()) {
    ACTOPO_ASSIGN_OR_RETURN(upload, Create(core, infos));
  } else {
    ACTOPO_ASSIGN_OR_RETURN(upload, Get(core, options.upload_id));
    if (!SameFiles(upload.files, infos)) {
      return absl::FailedPreconditionError(
          absl::StrCat("options.upload_id: upload '", options.upload_id, "' holds ",
                       Describe(upload.files), "; this call uploads ", Describe(infos)));
    }
  }
  report.state.upload_id = upload.upload_id;
  DeleteUnlessKept guard(core, upload.upload_id);
  ACTOPO_ASSIGN_OR_RETURN(
      upload, Send(core, files, std::move(upload), options, on_cancel, pause, report, guard));

  // The server takes the upload out of its spool as the load begins: while it still holds it,
  // a load whose call broke never began and may be asked again.
  v1::LoadMeshRequest request;
  request.set_upload(upload.upload_id);
  *request.mutable_partition() = internal::ToProto(options.partition);
  const LoadOptions load{.partition = options.partition,
                         .progress =
                             [&](const LoadProgress& p) {
                               report.Report(p.phase, p.fraction, report.state.total_bytes);
                             },
                         .cancel = options.cancel};
  for (int failures = 0;;) {
    absl::StatusOr<MeshInfo> mesh = internal::LoadWithProgress(core, request, load, on_cancel);
    if (mesh.ok() || mesh.status().code() != absl::StatusCode::kUnavailable || pause.cancelled()) {
      if (mesh.ok()) guard.Keep();  // the server dropped it
      return mesh;
    }
    if (++failures > options.max_resumes) {
      guard.Keep();
      return GaveUp(mesh.status(), upload, report.state.total_bytes, failures - 1,
                    "load it with LoadUpload");
    }
    if (!pause.Wait(Backoff(failures))) return absl::CancelledError("upload: cancelled");
    // NOT_FOUND: the server took it, the load began; its outcome went with the connection.
    absl::StatusOr<UploadStatus> held = Get(core, upload.upload_id);
    if (!held.ok() && !Resumable(held.status(), /*write=*/false)) return mesh.status();
  }
}

}  // namespace

absl::StatusOr<std::string> FileSha256(std::string_view path) {
  ACTOPO_ASSIGN_OR_RETURN(auto digest, Hash(fs::path(std::string(path)), nullptr));
  return std::move(digest.first);
}

absl::StatusOr<MeshInfo> Client::UploadFile(std::string_view path,
                                            const UploadFileOptions& options) {
  return UploadFileImpl(*core_, std::string(path), options, [&](std::function<void()> f) {
    return options.cancel.OnCancel(std::move(f));
  });
}

absl::StatusOr<UploadStatus> Client::CreateUpload(const std::vector<UploadFileInfo>& files) {
  return Create(*core_, files);
}

absl::StatusOr<UploadStatus> Client::WriteUpload(std::string_view upload_id, int32_t file,
                                                 int64_t offset, std::span<const std::byte> bytes,
                                                 size_t chunk_bytes) {
  if (chunk_bytes == 0) {
    return absl::InvalidArgumentError("chunk_bytes: 0; expected a positive size");
  }
  const Fill fill = [&](int64_t at, size_t n, std::string* chunk) {
    const std::span<const std::byte> part = bytes.subspan(size_t(at - offset), n);
    chunk->assign(reinterpret_cast<const char*>(part.data()), part.size());
    return absl::OkStatus();
  };
  absl::Status local;
  return Stream(
      *core_, std::string(upload_id), file, offset, offset + int64_t(bytes.size()), chunk_bytes,
      fill, nullptr, [](std::function<void()>) { return nullptr; }, &local);
}

absl::StatusOr<UploadStatus> Client::GetUpload(std::string_view upload_id) {
  return Get(*core_, upload_id);
}

absl::Status Client::DeleteUpload(std::string_view upload_id) {
  return Delete(*core_, *core_->stub, upload_id);
}

absl::StatusOr<MeshInfo> Client::LoadUpload(std::string_view upload_id,
                                            const LoadOptions& options) {
  ACTOPO_RETURN_IF_ERROR(CheckPartition(options.partition));
  v1::LoadMeshRequest request;
  request.set_upload(std::string(upload_id));
  *request.mutable_partition() = internal::ToProto(options.partition);
  return internal::LoadWithProgress(
      *core_, std::move(request), options,
      [&](std::function<void()> f) { return options.cancel.OnCancel(std::move(f)); });
}

absl::StatusOr<MeshInfo> Client::LoadUpload(std::string_view upload_id) {
  return LoadUpload(upload_id, LoadOptions());
}

}  // namespace actopo::client
