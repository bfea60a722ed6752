// Uploads of mesh files as their bytes (CreateUpload, WriteUpload, GetUpload, DeleteUpload and
// LoadMesh from an upload) on a real server: resumption, the digest, bad input, the budget.
#include <fstream>

#include "server/algorithms/digest.h"
#include "server/core/testing/wait.h"
#include "server/service/testing/service_fixture.h"

namespace actopo::service {
namespace {

using testing::ServiceTest;

std::string Slurp(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

class UploadsTest : public ServiceTest {
 protected:
  grpc::Status Create(const std::vector<std::pair<std::string, std::string>>& files,
                      v1::UploadStatus* status) {
    v1::CreateUploadRequest request;
    for (const auto& [path, bytes] : files) {
      v1::UploadFileInfo* f = request.add_files();
      f->set_path(path);
      f->set_size(int64_t(bytes.size()));
      f->set_sha256(Sha256Hex(bytes));
    }
    v1::CreateUploadResponse response;
    const grpc::Status s = stub_->CreateUpload(Context().get(), request, &response);
    *status = response.upload();
    return s;
  }

  // Sends bytes [offset, end) of `bytes` as file `file` in chunks of `chunk`; with `cut`, the
  // call is cancelled after that many chunks instead of finished.
  grpc::Status Write(const std::string& id, int file, const std::string& bytes, int64_t offset,
                     int64_t end, v1::UploadStatus* status, size_t chunk = 1000, int cut = -1) {
    auto context = Context();
    v1::WriteUploadResponse response;
    auto writer = stub_->WriteUpload(context.get(), &response);
    v1::WriteUploadRequest start;
    start.mutable_start()->set_upload_id(id);
    start.mutable_start()->set_file(file);
    start.mutable_start()->set_offset(offset);
    writer->Write(start);
    int sent = 0;
    for (int64_t at = offset; at < end; at += int64_t(chunk), ++sent) {
      if (sent == cut) {
        context->TryCancel();
        break;
      }
      v1::WriteUploadRequest m;
      m.set_chunk(bytes.substr(size_t(at), std::min<size_t>(chunk, size_t(end - at))));
      if (!writer->Write(m)) break;
    }
    writer->WritesDone();
    const grpc::Status s = writer->Finish();
    if (status != nullptr) *status = response.upload();
    return s;
  }

  grpc::Status Get(const std::string& id, v1::UploadStatus* status) {
    v1::GetUploadRequest request;
    request.set_upload_id(id);
    v1::GetUploadResponse response;
    const grpc::Status s = stub_->GetUpload(Context().get(), request, &response);
    *status = response.upload();
    return s;
  }

  grpc::Status LoadUpload(const std::string& id, v1::MeshInfo* mesh) {
    v1::LoadMeshRequest request;
    request.set_upload(id);
    v1::LoadMeshResponse response;
    const grpc::Status s = stub_->LoadMesh(Context().get(), request, &response);
    *mesh = response.mesh();
    return s;
  }
};

// Half the file, the call cut, the rest from where the server is: the mesh loaded from the
// upload equals the one loaded from the same file in the data directory, and the upload is gone.
TEST_F(UploadsTest, ACutUploadResumesAndLoadsAsTheFileDoes) {
  const std::string bytes = Slurp(data_dir_ / "sub" / "cube.vtu");
  ASSERT_GT(bytes.size(), 4000u);
  v1::UploadStatus status;
  ASSERT_TRUE(Create({{"cube.vtu", bytes}}, &status).ok());
  const std::string id = status.upload_id();
  EXPECT_EQ(status.received_bytes(0), 0);
  EXPECT_FALSE(status.complete());
  EXPECT_GT(status.expires_in_seconds(), 0);
  const int64_t half = int64_t(bytes.size()) / 2;
  ASSERT_TRUE(Write(id, 0, bytes, 0, half, &status).ok());
  EXPECT_EQ(status.received_bytes(0), half);
  // A call cut after two chunks keeps what the server appended (two chunks at most).
  EXPECT_FALSE(Write(id, 0, bytes, half, int64_t(bytes.size()), nullptr, 1000, 2).ok());
  ASSERT_TRUE(Get(id, &status).ok());
  const int64_t held = status.received_bytes(0);
  EXPECT_GE(held, half);
  EXPECT_LE(held, half + 2000);
  // Past what the server holds: refused, naming what it holds. Past the cut call's two chunks,
  // which the server may still be appending after the client's Finish and the Get above (a
  // start at or below what it holds is a resumption, accepted).
  const int64_t past = half + 2001;
  const grpc::Status wrong = Write(id, 0, bytes, past, past + 10, nullptr);
  EXPECT_EQ(wrong.error_code(), grpc::StatusCode::FAILED_PRECONDITION);
  EXPECT_NE(
      wrong.error_message().find("offset: " + std::to_string(past) + ", but the server holds "),
      std::string::npos)
      << wrong.error_message();
  v1::MeshInfo mesh;
  EXPECT_EQ(LoadUpload(id, &mesh).error_code(), grpc::StatusCode::FAILED_PRECONDITION);
  ASSERT_TRUE(Write(id, 0, bytes, held, int64_t(bytes.size()), &status).ok());
  EXPECT_TRUE(status.complete());

  ASSERT_TRUE(LoadUpload(id, &mesh).ok());
  v1::LoadMeshRequest by_path;
  by_path.set_path("sub/cube.vtu");
  v1::LoadMeshResponse reference;
  ASSERT_TRUE(stub_->LoadMesh(Context().get(), by_path, &reference).ok());
  EXPECT_EQ(mesh.vertices(), reference.mesh().vertices());
  EXPECT_EQ(mesh.tetrahedra(), reference.mesh().tetrahedra());
  EXPECT_EQ(mesh.source(), "upload:cube.vtu");
  EXPECT_EQ(Get(id, &status).error_code(), grpc::StatusCode::NOT_FOUND);
}

// A .pvd and the files it names, under the relative paths it names them by.
TEST_F(UploadsTest, ASeriesUploadsWithItsFiles) {
  const std::string step = Slurp(data_dir_ / "sub" / "cube.vtu");
  const std::string pvd =
      "<?xml version=\"1.0\"?><VTKFile type=\"Collection\" version=\"0.1\"><Collection>"
      "<DataSet timestep=\"0\" file=\"steps/a.vtu\"/><DataSet timestep=\"1.5\" "
      "file=\"steps/b.vtu\"/></Collection></VTKFile>";
  v1::UploadStatus status;
  ASSERT_TRUE(
      Create({{"run.pvd", pvd}, {"steps/a.vtu", step}, {"steps/b.vtu", step}}, &status).ok());
  const std::string id = status.upload_id();
  ASSERT_TRUE(Write(id, 0, pvd, 0, int64_t(pvd.size()), nullptr).ok());
  ASSERT_TRUE(Write(id, 1, step, 0, int64_t(step.size()), nullptr).ok());
  ASSERT_TRUE(Write(id, 2, step, 0, int64_t(step.size()), &status).ok());
  EXPECT_TRUE(status.complete());
  v1::MeshInfo mesh;
  const grpc::Status loaded = LoadUpload(id, &mesh);
  ASSERT_TRUE(loaded.ok()) << loaded.error_message();
  int series_fields = 0;
  for (const v1::FieldInfo& f : mesh.fields()) series_fields += f.has_time();
  EXPECT_EQ(series_fields, 2 * 2);  // two fields per step (scalar, height), two steps
}

// Bad input: each its status, the upload gone after it, the server's budget free again.
TEST_F(UploadsTest, BadUploadsAreDroppedWithTheirReason) {
  const std::string bytes = Slurp(data_dir_ / "sub" / "cube.vtu");
  v1::UploadStatus status;
  // A wrong digest: DATA_LOSS at the last byte.
  v1::CreateUploadRequest create;
  v1::UploadFileInfo* f = create.add_files();
  f->set_path("cube.vtu");
  f->set_size(int64_t(bytes.size()));
  f->set_sha256(Sha256Hex("something else"));
  v1::CreateUploadResponse created;
  ASSERT_TRUE(stub_->CreateUpload(Context().get(), create, &created).ok());
  grpc::Status s = Write(created.upload().upload_id(), 0, bytes, 0, int64_t(bytes.size()), nullptr);
  EXPECT_EQ(s.error_code(), grpc::StatusCode::DATA_LOSS) << s.error_message();
  EXPECT_EQ(Get(created.upload().upload_id(), &status).error_code(), grpc::StatusCode::NOT_FOUND);
  // More bytes than announced.
  ASSERT_TRUE(Create({{"cube.vtu", bytes.substr(0, 100)}}, &status).ok());
  s = Write(status.upload_id(), 0, bytes, 0, 200, nullptr);
  EXPECT_EQ(s.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_NE(s.error_message().find("more than the 100 bytes announced"), std::string::npos);
  // Not a mesh: the load names the file, and the upload is gone.
  const std::string text = "just text\n";
  ASSERT_TRUE(Create({{"notes.vtu", text}}, &status).ok());
  ASSERT_TRUE(Write(status.upload_id(), 0, text, 0, int64_t(text.size()), nullptr).ok());
  v1::MeshInfo mesh;
  s = LoadUpload(status.upload_id(), &mesh);
  EXPECT_EQ(s.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_NE(s.error_message().find("notes.vtu"), std::string::npos) << s.error_message();
  EXPECT_EQ(s.error_message().find(data_dir_.string()), std::string::npos) << s.error_message();
  EXPECT_EQ(Get(status.upload_id(), &status).error_code(), grpc::StatusCode::NOT_FOUND);
  // A collection that lists nothing: its error names it as the client did.
  const std::string empty =
      "<?xml version=\"1.0\"?><VTKFile type=\"Collection\"><Collection/></VTKFile>";
  ASSERT_TRUE(Create({{"empty.pvd", empty}}, &status).ok());
  ASSERT_TRUE(Write(status.upload_id(), 0, empty, 0, int64_t(empty.size()), nullptr).ok());
  s = LoadUpload(status.upload_id(), &mesh);
  EXPECT_FALSE(s.ok());
  EXPECT_NE(s.error_message().find("empty.pvd"), std::string::npos) << s.error_message();
  EXPECT_EQ(s.error_message().find("actopo-uploads"), std::string::npos) << s.error_message();
  // A first message that is not the start; an unknown upload; a file index out of range.
  s = Write("upload-nope", 0, bytes, 0, 10, nullptr);
  EXPECT_EQ(s.error_code(), grpc::StatusCode::NOT_FOUND);
  EXPECT_NE(s.error_message().find("upload-nope"), std::string::npos);
  ASSERT_TRUE(Create({{"cube.vtu", bytes}}, &status).ok());
  s = Write(status.upload_id(), 3, bytes, 0, 10, nullptr);
  EXPECT_EQ(s.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_NE(s.error_message().find("file: 3"), std::string::npos) << s.error_message();
  {
    auto context = Context();
    v1::WriteUploadResponse response;
    auto writer = stub_->WriteUpload(context.get(), &response);
    v1::WriteUploadRequest chunk;
    chunk.set_chunk("abc");
    writer->Write(chunk);
    writer->WritesDone();
    s = writer->Finish();
    EXPECT_EQ(s.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
    EXPECT_NE(s.error_message().find("start"), std::string::npos) << s.error_message();
  }
  v1::DeleteUploadRequest del;
  del.set_upload_id(status.upload_id());
  v1::DeleteUploadResponse deleted;
  EXPECT_TRUE(stub_->DeleteUpload(Context().get(), del, &deleted).ok());
  EXPECT_EQ(stub_->DeleteUpload(Context().get(), del, &deleted).error_code(),
            grpc::StatusCode::NOT_FOUND);
  // Still serving.
  EXPECT_FALSE(LoadSample("jittered:4").empty());
}

// The budget: an upload larger than it is refused at once; an abandoned one is dropped after
// the timeout, its share free again.
TEST_F(UploadsTest, TheBudgetAndTheTimeoutHold) {
  options_.upload_budget_bytes = 10000;
  options_.upload_timeout = absl::Seconds(1);
  StartServer();
  v1::UploadStatus status;
  const grpc::Status big = Create({{"big.vtu", std::string(10001, 'x')}}, &status);
  EXPECT_EQ(big.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED);
  EXPECT_NE(big.error_message().find("an upload of 10001 bytes"), std::string::npos)
      << big.error_message();
  ASSERT_TRUE(Create({{"a.vtu", std::string(6000, 'x')}}, &status).ok());
  EXPECT_EQ(Create({{"b.vtu", std::string(6000, 'x')}}, &status).error_code(),
            grpc::StatusCode::RESOURCE_EXHAUSTED);
  // Left alone, the first is dropped: the second fits then.
  EXPECT_TRUE(actopo::testing::WaitUntil([&] {
    return Create({{"b.vtu", std::string(6000, 'x')}}, &status).ok();
  }));
  v1::GetServerInfoResponse info;
  ASSERT_TRUE(stub_->GetServerInfo(Context().get(), {}, &info).ok());
  EXPECT_EQ(info.limits().upload_budget_bytes(), 10000);
  EXPECT_EQ(info.limits().upload_timeout_seconds(), 1);
}

}  // namespace
}  // namespace actopo::service
