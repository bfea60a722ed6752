// Mesh files uploaded as their bytes, resumably (CreateUpload, WriteUpload, GetUpload,
// DeleteUpload; LoadMesh with source `upload` reads one).
//
//   ASSIGN_OR_RETURN(std::string id, spool.Create({{"wave.vtu", size, sha256}}));
//   ASSIGN_OR_RETURN(UploadSpool::Writer w, spool.Write(id, /*file=*/0, /*offset=*/0));
//   RETURN_IF_ERROR(w.Append(chunk));       // ... as the chunks come
//   ASSIGN_OR_RETURN(UploadSpool::Taken t, spool.Take(id));  // complete: read t.main_file()
//
// Each upload is a folder of the spool holding its files under the relative paths the client
// gave (a .pvd beside the files it names). Bytes are written as they arrive and hashed as they
// are written, so a broken connection loses nothing the server acknowledged: the client asks how
// many bytes the server holds (Get) and goes on from there. A file's SHA-256 is checked when its
// last byte arrives; more bytes than announced, or a wrong digest, drop the upload. The sizes
// announced are reserved in the spool's budget when the upload is created, and stay reserved
// until it is taken, deleted, or dropped for being left alone longer than the timeout.
#ifndef ACTOPO_SERVER_SERVICE_UPLOAD_SPOOL_H_
#define ACTOPO_SERVER_SERVICE_UPLOAD_SPOOL_H_

#include <chrono>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <string>
#include <string_view>
#include <thread>
#include <vector>

#include "absl/container/flat_hash_map.h"
#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "server/core/sync.h"
#include "server/service/memory_budget.h"

namespace actopo::service {

struct UploadSpoolOptions {
  std::filesystem::path dir;                // made if missing; each upload is a folder in it
  int64_t budget_bytes = int64_t(8) << 30;  // the sizes of the uploads held at once
  std::chrono::seconds timeout{900};        // an upload nobody writes to this long is dropped
  int max_uploads = 64;                     // uploads held at once
};

class UploadSpool {
 public:
  struct FileSpec {
    std::string path;    // relative, '/'-separated, no '..'; the first is the mesh to read
    int64_t size = 0;    // bytes
    std::string sha256;  // lowercase hex
  };
  struct State {
    std::vector<FileSpec> files;
    std::vector<int64_t> received;  // per file: the bytes the server holds
    bool complete = false;          // every byte of every file, each digest checked
    std::chrono::seconds expires_in{0};
  };

  // The one writer of an upload's file at a time: appends at the offset it holds. A newer
  // writer of the upload takes it over (Write); this one's appends are then ABORTED.
  class Writer {
   public:
    Writer(Writer&&) noexcept;
    Writer& operator=(Writer&&) = delete;
    ~Writer();  // lets another writer take the upload (a broken stream leaves what it wrote)
    // Appends `bytes`; on the file's last byte checks its digest. INVALID_ARGUMENT past the
    // announced size, DATA_LOSS on a wrong digest: the upload is dropped then.
    absl::Status Append(std::string_view bytes);
    int64_t received() const;

   private:
    friend class UploadSpool;
    struct Upload;
    Writer(UploadSpool* spool, std::shared_ptr<Upload> upload, int file, int fd,
           uint64_t generation);
    UploadSpool* spool_;
    std::shared_ptr<Upload> upload_;
    int file_;
    int fd_;
    uint64_t generation_;
  };

  // A complete upload taken out of the spool for reading; its folder goes with it.
  class Taken {
   public:
    Taken(Taken&&) noexcept;
    Taken& operator=(Taken&&) = delete;
    ~Taken();
    const std::filesystem::path& dir() const { return dir_; }
    // The relative path of the file to read (the first announced).
    const std::string& main_file() const { return main_; }

   private:
    friend class UploadSpool;
    Taken(std::filesystem::path dir, std::string main, Reservation reservation);
    std::filesystem::path dir_;
    std::string main_;
    Reservation reservation_;
  };

  // Makes options.dir if missing, takes it (a lock on its kLockFile, held until the spool is
  // gone: FAILED_PRECONDITION while another server's spool holds the folder) and removes the
  // upload folders an earlier run left there.
  static absl::StatusOr<std::unique_ptr<UploadSpool>> Open(const UploadSpoolOptions& options);
  ~UploadSpool();  // removes every upload's folder, and options.dir if it made it
  // Removes the folders in `parent` named PREFIX<pid>-... that no running spool holds: those of
  // servers killed before they could clean up (the kernel drops a dead process's lock). An
  // unlocked folder goes when its process is gone, or when its lock file is over a minute old
  // (the process id was reused); a folder without a lock file (an older server's) only in the
  // first case. Returns how many went.
  static int RemoveAbandoned(const std::filesystem::path& parent, std::string_view prefix);
  static constexpr char kLockFile[] = ".actopo-spool.lock";

  // A new upload of `files`; errors name `files[k].path`, `.size` or `.sha256`.
  absl::StatusOr<std::string> Create(std::vector<FileSpec> files);
  // The writer of file `file` of upload `id` from `offset`, at most what the server holds of it
  // (FAILED_PRECONDITION naming both otherwise; the bytes after `offset` go). It takes the
  // upload over from a writer that still holds it: a client resuming after a broken connection
  // need not wait for the server to notice the old call's end, nor for it to stop appending
  // what had come before the break.
  absl::StatusOr<Writer> Write(const std::string& id, int file, int64_t offset);
  absl::StatusOr<State> Get(const std::string& id);
  absl::Status Delete(const std::string& id);
  // A complete upload for reading (FAILED_PRECONDITION naming what is missing otherwise).
  absl::StatusOr<Taken> Take(const std::string& id);

  int64_t used_bytes() const { return budget_.used(); }
  int64_t budget_bytes() const { return budget_.limit(); }
  int size() const;

 private:
  explicit UploadSpool(const UploadSpoolOptions& options);
  absl::StatusOr<std::shared_ptr<Writer::Upload>> Find(const std::string& id)
      ABSL_EXCLUSIVE_LOCKS_REQUIRED(mu_);
  void Drop(const std::string& id) ABSL_EXCLUSIVE_LOCKS_REQUIRED(mu_);
  void DropNow(const std::string& id);  // takes the mutex
  void ReapExpired();

  const UploadSpoolOptions options_;
  MemoryBudget budget_;
  mutable Mutex mu_;
  absl::flat_hash_map<std::string, std::shared_ptr<Writer::Upload>> uploads_ ABSL_GUARDED_BY(mu_);
  bool stopping_ ABSL_GUARDED_BY(mu_) = false;
  bool made_dir_ = false;
  int lock_fd_ = -1;  // holds the lock on options_.dir / kLockFile
  CondVar reaper_cv_;
  std::thread reaper_;
};

}  // namespace actopo::service

#endif  // ACTOPO_SERVER_SERVICE_UPLOAD_SPOOL_H_
