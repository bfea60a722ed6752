#include "server/service/upload_spool.h"

#include <sys/wait.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <latch>
#include <string>
#include <thread>

#include "gtest/gtest.h"
#include "server/algorithms/digest.h"
#include "server/core/testing/status.h"
#include "server/core/testing/wait.h"

namespace actopo::service {
namespace {

std::filesystem::path TempDir(const std::string& name) {
  return std::filesystem::temp_directory_path() /
         (name + "_" + std::to_string(::getpid()) + "_" +
          ::testing::UnitTest::GetInstance()->current_test_info()->name());
}

std::string Bytes(size_t n, char seed) {
  std::string s(n, '\0');
  for (size_t i = 0; i < n; ++i) s[i] = char(seed + i * 7 % 251);
  return s;
}

std::string Slurp(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

std::unique_ptr<UploadSpool> OpenSpool(int64_t budget = 1 << 20,
                                       std::chrono::seconds timeout = std::chrono::seconds(900)) {
  return OkValue(UploadSpool::Open(
      {.dir = TempDir("spool"), .budget_bytes = budget, .timeout = timeout, .max_uploads = 4}));
}

// Bytes written in pieces, a stream broken after some (the writer goes), the rest sent from
// where the server is: the file holds exactly the bytes, its digest checked, and Take hands it
// over with its folder, which goes with the Taken.
TEST(UploadSpool, ResumesFromWhatItHoldsAndHandsOverTheFiles) {
  auto spool = OpenSpool();
  const std::string mesh = Bytes(10000, 'a'), step = Bytes(300, 'q');
  const std::string id =
      OkValue(spool->Create({{"series.pvd", int64_t(mesh.size()), Sha256Hex(mesh)},
                             {"steps/s_0.vtu", int64_t(step.size()), Sha256Hex(step)}}));
  {
    UploadSpool::Writer w = OkValue(spool->Write(id, 0, 0));
    ASSERT_TRUE(w.Append(std::string_view(mesh).substr(0, 4000)).ok());
    ASSERT_TRUE(w.Append(std::string_view(mesh).substr(4000, 1000)).ok());
    EXPECT_EQ(w.received(), 5000);
    // A newer call takes the upload over (a client resuming after a broken connection that the
    // server has not noticed yet): the first writer's appends are refused from then on.
    {
      UploadSpool::Writer newer = OkValue(spool->Write(id, 0, 5000));
      EXPECT_EQ(w.Append("more").code(), absl::StatusCode::kAborted);
      EXPECT_EQ(newer.received(), 5000);
    }
  }  // the stream breaks here
  UploadSpool::State state = OkValue(spool->Get(id));
  EXPECT_EQ(state.received, (std::vector<int64_t>{5000, 0}));
  EXPECT_FALSE(state.complete);
  // An offset past what the server holds names what it holds.
  const absl::Status wrong = spool->Write(id, 0, 5001).status();
  EXPECT_EQ(wrong.code(), absl::StatusCode::kFailedPrecondition);
  EXPECT_NE(wrong.message().find("holds 5000 bytes of files[0] 'series.pvd'"), std::string::npos)
      << wrong;
  // One before it goes on from there: the bytes after it go, the digest follows.
  {
    UploadSpool::Writer w = OkValue(spool->Write(id, 0, 4096));
    EXPECT_EQ(w.received(), 4096);
    ASSERT_TRUE(w.Append(std::string_view(mesh).substr(4096, 904)).ok());
  }
  EXPECT_EQ(spool->Take(id).status().code(), absl::StatusCode::kFailedPrecondition);
  {
    UploadSpool::Writer w = OkValue(spool->Write(id, 0, 5000));
    ASSERT_TRUE(w.Append(std::string_view(mesh).substr(5000)).ok());
  }
  {
    UploadSpool::Writer w = OkValue(spool->Write(id, 1, 0));
    ASSERT_TRUE(w.Append(step).ok());
  }
  state = OkValue(spool->Get(id));
  EXPECT_TRUE(state.complete);
  EXPECT_EQ(spool->used_bytes(), int64_t(mesh.size() + step.size()));
  std::filesystem::path dir;
  {
    const UploadSpool::Taken taken = OkValue(spool->Take(id));
    dir = taken.dir();
    EXPECT_EQ(taken.main_file(), "series.pvd");
    EXPECT_EQ(Slurp(dir / "series.pvd"), mesh);
    EXPECT_EQ(Slurp(dir / "steps/s_0.vtu"), step);
    EXPECT_EQ(spool->Get(id).status().code(), absl::StatusCode::kNotFound);
  }
  EXPECT_FALSE(std::filesystem::exists(dir));
  EXPECT_EQ(spool->used_bytes(), 0);
}

// What cannot be right drops the upload: bytes past the size, a wrong digest. Its folder and its
// share of the budget go at once.
TEST(UploadSpool, TooManyBytesOrAWrongDigestDropTheUpload) {
  auto spool = OpenSpool();
  const std::string bytes = Bytes(1000, 'x');
  const std::string long_one = OkValue(spool->Create({{"a.vtu", 999, Sha256Hex(bytes)}}));
  {
    UploadSpool::Writer w = OkValue(spool->Write(long_one, 0, 0));
    const absl::Status s = w.Append(bytes);
    EXPECT_EQ(s.code(), absl::StatusCode::kInvalidArgument);
    EXPECT_NE(s.message().find("more than the 999 bytes announced (1000 sent)"), std::string::npos)
        << s;
  }
  EXPECT_EQ(spool->Get(long_one).status().code(), absl::StatusCode::kNotFound);
  const std::string wrong = OkValue(spool->Create({{"a.vtu", 1000, Sha256Hex("other")}}));
  {
    UploadSpool::Writer w = OkValue(spool->Write(wrong, 0, 0));
    const absl::Status s = w.Append(bytes);
    EXPECT_EQ(s.code(), absl::StatusCode::kDataLoss);
    EXPECT_NE(s.message().find("not the announced"), std::string::npos) << s;
  }
  EXPECT_EQ(spool->Get(wrong).status().code(), absl::StatusCode::kNotFound);
  EXPECT_EQ(spool->used_bytes(), 0);
  EXPECT_EQ(spool->size(), 0);
}

TEST(UploadSpool, BadAnnouncementsNameTheirField) {
  auto spool = OpenSpool(/*budget=*/1000);
  const std::string digest = Sha256Hex("x");
  struct Case {
    std::vector<UploadSpool::FileSpec> files;
    absl::StatusCode code;
    std::string message;
  };
  const Case cases[] = {
      {{}, absl::StatusCode::kInvalidArgument, "files: none"},
      {{{"../x.vtu", 1, digest}}, absl::StatusCode::kInvalidArgument, "files[0].path: '../x.vtu'"},
      {{{"/etc/x.vtu", 1, digest}}, absl::StatusCode::kInvalidArgument, "files[0].path"},
      {{{"a//b.vtu", 1, digest}}, absl::StatusCode::kInvalidArgument, "has a part ''"},
      {{{"a.vtu", -1, digest}}, absl::StatusCode::kInvalidArgument, "files[0].size: -1"},
      {{{"a.vtu", 1, "ABC"}}, absl::StatusCode::kInvalidArgument, "files[0].sha256: 'ABC'"},
      {{{"a.vtu", 1, digest}, {"a.vtu", 1, digest}},
       absl::StatusCode::kInvalidArgument,
       "files[1].path: 'a.vtu' is files[0] too"},
      {{{"a.vtu", 1001, digest}}, absl::StatusCode::kResourceExhausted, "an upload of 1001 bytes"},
      {{{"a.vtu", 0, digest}}, absl::StatusCode::kInvalidArgument, "not the digest of an empty"},
  };
  for (const Case& c : cases) {
    const absl::Status s = spool->Create(c.files).status();
    EXPECT_EQ(s.code(), c.code) << s;
    EXPECT_NE(s.message().find(c.message), std::string::npos) << s;
  }
  EXPECT_EQ(spool->size(), 0);
  EXPECT_EQ(spool->used_bytes(), 0);
  EXPECT_EQ(spool->Write("upload-nope", 0, 0).status().code(), absl::StatusCode::kNotFound);
}

// An upload nobody writes to is dropped after the timeout, with its budget; one written to in
// time stays.
TEST(UploadSpool, AnAbandonedUploadIsDroppedAfterTheTimeout) {
  auto spool = OpenSpool(1 << 20, std::chrono::seconds(1));
  const std::string bytes = Bytes(100, 'z');
  const std::string id = OkValue(spool->Create({{"a.vtu", 100, Sha256Hex(bytes)}}));
  EXPECT_EQ(spool->used_bytes(), 100);
  ASSERT_TRUE(actopo::testing::WaitUntil([&] { return spool->size() == 0; }));
  EXPECT_EQ(spool->Get(id).status().code(), absl::StatusCode::kNotFound);
  EXPECT_EQ(spool->used_bytes(), 0);
}

// Writers of different uploads run at once; Get and Delete meanwhile are safe (run under TSan).
TEST(UploadSpool, UploadsAreWrittenConcurrently) {
  auto spool = OpenSpool(int64_t(1) << 24);
  const std::string bytes = Bytes(200000, 'k');
  std::vector<std::string> ids;
  for (int i = 0; i < 3; ++i) {
    ids.push_back(OkValue(spool->Create({{"m.vtu", int64_t(bytes.size()), Sha256Hex(bytes)}})));
  }
  std::latch start(4);
  std::vector<std::thread> writers;
  for (const std::string& id : ids) {
    writers.emplace_back([&, id] {
      start.arrive_and_wait();
      UploadSpool::Writer w = OkValue(spool->Write(id, 0, 0));
      for (size_t at = 0; at < bytes.size(); at += 4096) {
        EXPECT_TRUE(w.Append(std::string_view(bytes).substr(at, 4096)).ok());
        (void)spool->Get(id);
      }
    });
  }
  start.arrive_and_wait();
  for (int i = 0; i < 50; ++i) (void)spool->Get(ids[i % 3]);
  for (std::thread& t : writers) t.join();
  for (const std::string& id : ids) EXPECT_TRUE(OkValue(spool->Get(id)).complete);
  EXPECT_TRUE(spool->Delete(ids[0]).ok());
  EXPECT_EQ(spool->size(), 2);
}

// A folder is one spool's while it is open: a second server is refused it, by name.
TEST(UploadSpool, AFolderHoldsOneSpoolAtATime) {
  auto spool = OpenSpool();
  const absl::StatusOr<std::unique_ptr<UploadSpool>> second =
      UploadSpool::Open({.dir = TempDir("spool")});
  ASSERT_EQ(second.status().code(), absl::StatusCode::kFailedPrecondition);
  EXPECT_NE(second.status().message().find("in use by another running server"), std::string::npos)
      << second.status();
  EXPECT_NE(second.status().message().find(TempDir("spool").string()), std::string::npos);
  spool.reset();
  EXPECT_TRUE(UploadSpool::Open({.dir = TempDir("spool")}).ok());  // free again
}

// What killed servers left goes; a running spool's folder, a folder of a live process being
// made, and other names stay.
TEST(UploadSpool, RemoveAbandonedTakesOnlyWhatNoRunningServerHolds) {
  const std::filesystem::path parent = TempDir("parent");
  std::filesystem::remove_all(parent);
  std::filesystem::create_directories(parent);
  const std::string prefix = "actopo-uploads-";
  const std::string self = std::to_string(::getpid());
  const pid_t child = ::fork();  // a process id that is gone once it is waited for
  if (child == 0) ::_exit(0);
  ASSERT_GT(child, 0);
  ASSERT_EQ(::waitpid(child, nullptr, 0), child);
  const std::string gone = std::to_string(child);
  const auto folder = [&](const std::string& name, bool lock_file) {
    std::filesystem::create_directories(parent / name / "upload-x");
    std::ofstream(parent / name / "upload-x" / "mesh.vtu") << "bytes";
    if (lock_file) std::ofstream(parent / name / UploadSpool::kLockFile).put('\n');
    return parent / name;
  };
  auto running = OkValue(UploadSpool::Open({.dir = parent / (prefix + self + "-running")}));
  const auto killed = folder(prefix + gone + "-killed", true);  // its lock dropped with it
  const auto older = folder(prefix + gone + "-older", false);   // a server from before locks
  const auto reused = folder(prefix + self + "-reused", true);  // its pid now someone else's
  std::filesystem::last_write_time(
      reused / UploadSpool::kLockFile,
      std::filesystem::file_time_type::clock::now() - std::chrono::minutes(2));
  const auto starting = folder(prefix + self + "-starting", true);  // not locked yet
  const auto unlocked = folder(prefix + self + "-unlocked", false);
  const auto other = folder("something-else", true);

  EXPECT_EQ(UploadSpool::RemoveAbandoned(parent, prefix), 3);
  EXPECT_FALSE(std::filesystem::exists(killed));
  EXPECT_FALSE(std::filesystem::exists(older));
  EXPECT_FALSE(std::filesystem::exists(reused));
  EXPECT_TRUE(
      std::filesystem::exists(parent / (prefix + self + "-running") / UploadSpool::kLockFile));
  EXPECT_TRUE(std::filesystem::exists(starting / "upload-x" / "mesh.vtu"));
  EXPECT_TRUE(std::filesystem::exists(unlocked));
  EXPECT_TRUE(std::filesystem::exists(other));
  running.reset();  // its folder goes with it
  EXPECT_FALSE(std::filesystem::exists(parent / (prefix + self + "-running")));
  std::filesystem::remove_all(parent);
}

}  // namespace
}  // namespace actopo::service
