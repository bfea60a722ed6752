// A corpus of bad requests, each answered with its expected code and a message naming the
#include <cmath>
#include <fstream>
#include <functional>
// offending field or value, while the server keeps serving a good request after each.
#include "server/algorithms/digest.h"
#include "server/service/testing/service_fixture.h"

namespace actopo::service {
namespace {

using testing::ServiceTest;

struct Case {
  std::string name;
  grpc::StatusCode code;
  std::string message;  // a substring of the error message
  std::function<grpc::Status(ServiceTest*, v1::TopologyService::Stub&, const std::string& mesh,
                             const std::string& session)>
      call;
};

class BadInputTest : public ServiceTest {
 public:
  grpc::Status Upload(const v1::UploadMeshHeader& header, const std::vector<std::string>& chunks) {
    v1::UploadMeshResponse response;
    auto context = Context();
    auto writer = stub_->UploadMesh(context.get(), &response);
    v1::UploadMeshRequest h;
    *h.mutable_header() = header;
    writer->Write(h);
    for (const std::string& c : chunks) {
      v1::UploadMeshRequest m;
      m.set_chunk(c);
      if (!writer->Write(m)) break;
    }
    writer->WritesDone();
    return writer->Finish();
  }
  grpc::Status Load(const std::string& path) {
    v1::LoadMeshRequest r;
    r.set_path(path);
    v1::LoadMeshResponse out;
    return stub_->LoadMesh(Context().get(), r, &out);
  }
  grpc::Status Relation(const std::string& session, v1::Relation relation, int64_t id) {
    v1::GetRelationRequest q;
    q.set_session_id(session);
    q.set_relation(relation);
    q.mutable_simplex()->set_id(id);
    v1::GetRelationResponse out;
    return stub_->GetRelation(Context().get(), q, &out);
  }
  grpc::Status Tuple(const std::string& session, v1::Relation relation,
                     std::vector<int64_t> vertices) {
    v1::GetRelationRequest q;
    q.set_session_id(session);
    q.set_relation(relation);
    for (int64_t v : vertices) q.mutable_simplex()->mutable_vertices()->add_ids(v);
    v1::GetRelationResponse out;
    return stub_->GetRelation(Context().get(), q, &out);
  }
};

// A valid upload of a single tetrahedron, to corrupt in the cases below.
struct TinyUpload {
  v1::UploadMeshHeader header;
  std::string bytes;
  TinyUpload(double scalar = 1.0, int32_t last_vertex = 3) {
    const double points[12] = {0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1};
    const int32_t tet[4] = {0, 1, 2, last_vertex};
    const double field[4] = {0, 0.5, 0.25, scalar};
    bytes.append(reinterpret_cast<const char*>(points), sizeof points);
    bytes.append(reinterpret_cast<const char*>(tet), sizeof tet);
    bytes.append(reinterpret_cast<const char*>(field), sizeof field);
    header.set_name("tiny");
    header.set_num_vertices(4);
    header.set_num_tetrahedra(1);
    header.set_points_dtype(v1::DATA_TYPE_FLOAT64);
    header.set_tetrahedra_dtype(v1::DATA_TYPE_INT32);
    auto* f = header.add_fields();
    f->set_name("s");
    f->set_dtype(v1::DATA_TYPE_FLOAT64);
    header.set_sha256(Sha256Hex(bytes));
  }
};

TEST_F(BadInputTest, EveryCaseGetsItsCodeAndTheServerKeepsServing) {
  std::filesystem::copy_file("/etc/hostname", data_dir_ / "notamesh.txt");
  {
    std::ofstream corrupt(data_dir_ / "corrupt.vtu");
    corrupt << "<?xml version=\"1.0\"?><VTKFile type=\"UnstructuredGrid\"><garbage";
  }
  const std::string mesh = LoadSample("jittered:5");
  const std::string session = Open(mesh, v1::STRUCTURE_ACTOPO);
  using C = grpc::StatusCode;
  std::vector<Case> cases = {
      {"path escaping the data dir", C::INVALID_ARGUMENT, "outside the server's data directory",
       [](auto* t, auto&, auto&, auto&) { return static_cast<BadInputTest*>(t)->Load("../../etc/passwd"); }},
      {"absolute path", C::INVALID_ARGUMENT, "outside",
       [](auto* t, auto&, auto&, auto&) { return static_cast<BadInputTest*>(t)->Load("/etc/passwd"); }},
      {"missing file", C::NOT_FOUND, "nope.vtu",
       [](auto* t, auto&, auto&, auto&) { return static_cast<BadInputTest*>(t)->Load("nope.vtu"); }},
      {"unknown extension", C::INVALID_ARGUMENT, ".txt",
       [](auto* t, auto&, auto&, auto&) { return static_cast<BadInputTest*>(t)->Load("notamesh.txt"); }},
      {"corrupt vtu", C::INVALID_ARGUMENT, "corrupt.vtu",
       [](auto* t, auto&, auto&, auto&) { return static_cast<BadInputTest*>(t)->Load("corrupt.vtu"); }},
      {"empty path", C::INVALID_ARGUMENT, "path",
       [](auto* t, auto&, auto&, auto&) { return static_cast<BadInputTest*>(t)->Load(""); }},
      {"unknown sample", C::INVALID_ARGUMENT, "sample 'teapot'",
       [](auto*, auto& stub, auto&, auto&) {
         v1::LoadMeshRequest r;
         r.set_sample("teapot");
         v1::LoadMeshResponse out;
         grpc::ClientContext c;
         return stub.LoadMesh(&c, r, &out);
       }},
      {"no source", C::INVALID_ARGUMENT, "source",
       [](auto*, auto& stub, auto&, auto&) {
         v1::LoadMeshResponse out;
         grpc::ClientContext c;
         return stub.LoadMesh(&c, v1::LoadMeshRequest(), &out);
       }},
      {"unknown mesh", C::NOT_FOUND, "mesh-nope",
       [](auto*, auto& stub, auto&, auto&) {
         v1::OpenSessionRequest r;
         r.set_mesh_id("mesh-nope");
         v1::OpenSessionResponse out;
         grpc::ClientContext c;
         return stub.OpenSession(&c, r, &out);
       }},
      {"unknown scalar field", C::NOT_FOUND, "'pressure' not found",
       [](auto*, auto& stub, auto& mesh, auto&) {
         v1::OpenSessionRequest r;
         r.set_mesh_id(mesh);
         r.set_scalar_field("pressure");
         v1::OpenSessionResponse out;
         grpc::ClientContext c;
         return stub.OpenSession(&c, r, &out);
       }},
      {"bad producers", C::INVALID_ARGUMENT, "engine.producers: 500",
       [](auto*, auto& stub, auto& mesh, auto&) {
         v1::OpenSessionRequest r;
         r.set_mesh_id(mesh);
         r.mutable_engine()->set_producers(500);
         v1::OpenSessionResponse out;
         grpc::ClientContext c;
         return stub.OpenSession(&c, r, &out);
       }},
      {"bad query readers", C::INVALID_ARGUMENT, "engine.query_readers: -1",
       [](auto*, auto& stub, auto& mesh, auto&) {
         v1::OpenSessionRequest r;
         r.set_mesh_id(mesh);
         r.mutable_engine()->set_query_readers(-1);
         v1::OpenSessionResponse out;
         grpc::ClientContext c;
         return stub.OpenSession(&c, r, &out);
       }},
      {"bad buffer ratio", C::INVALID_ARGUMENT, "engine.buffer_ratio: -2",
       [](auto*, auto& stub, auto& mesh, auto&) {
         v1::OpenSessionRequest r;
         r.set_mesh_id(mesh);
         r.mutable_engine()->set_buffer_ratio(-2);
         v1::OpenSessionResponse out;
         grpc::ClientContext c;
         return stub.OpenSession(&c, r, &out);
       }},
      {"unknown structure value", C::INVALID_ARGUMENT, "structure: 42",
       [](auto*, auto& stub, auto& mesh, auto&) {
         v1::OpenSessionRequest r;
         r.set_mesh_id(mesh);
         r.set_structure(static_cast<v1::Structure>(42));
         v1::OpenSessionResponse out;
         grpc::ClientContext c;
         return stub.OpenSession(&c, r, &out);
       }},
      {"unknown session", C::NOT_FOUND, "session-guess",
       [](auto* t, auto&, auto&, auto&) {
         return static_cast<BadInputTest*>(t)->Relation("session-guess", v1::RELATION_VERTEX_STAR, 0);
       }},
      {"vertex id past the end", C::OUT_OF_RANGE, "vertex id 125",
       [](auto* t, auto&, auto&, auto& s) {
         return static_cast<BadInputTest*>(t)->Relation(s, v1::RELATION_VERTEX_STAR, 125);
       }},
      {"negative tetrahedron id", C::OUT_OF_RANGE, "tetrahedron id -3",
       [](auto* t, auto&, auto&, auto& s) {
         return static_cast<BadInputTest*>(t)->Relation(s, v1::RELATION_TETRAHEDRON_NEIGHBORS, -3);
       }},
      {"relation unspecified", C::INVALID_ARGUMENT, "relation",
       [](auto* t, auto&, auto&, auto& s) {
         return static_cast<BadInputTest*>(t)->Relation(s, v1::RELATION_UNSPECIFIED, 0);
       }},
      {"relation out of the enum", C::INVALID_ARGUMENT, "relation: 99",
       [](auto* t, auto&, auto&, auto& s) {
         return static_cast<BadInputTest*>(t)->Relation(s, static_cast<v1::Relation>(99), 0);
       }},
      {"tuple of the wrong size", C::INVALID_ARGUMENT, "a triangle has 3 vertices, got 2",
       [](auto* t, auto&, auto&, auto& s) {
         return static_cast<BadInputTest*>(t)->Tuple(s, v1::RELATION_TRIANGLE_STAR, {0, 1});
       }},
      {"tuple that is not a simplex", C::NOT_FOUND, "is not a triangle",
       [](auto* t, auto&, auto&, auto& s) {
         return static_cast<BadInputTest*>(t)->Tuple(s, v1::RELATION_TRIANGLE_STAR, {0, 60, 124});
       }},
      {"tuple vertex out of range", C::OUT_OF_RANGE, "vertex id 1000",
       [](auto* t, auto&, auto&, auto& s) {
         return static_cast<BadInputTest*>(t)->Tuple(s, v1::RELATION_EDGE_STAR, {0, 1000});
       }},
      {"batch with float ids", C::INVALID_ARGUMENT, "ids.dtype",
       [](auto*, auto& stub, auto&, auto& s) {
         v1::GetRelationBatchRequest r;
         r.set_session_id(s);
         r.set_relation(v1::RELATION_VERTEX_STAR);
         r.mutable_ids()->set_dtype(v1::DATA_TYPE_FLOAT64);
         r.mutable_ids()->set_data(std::string(8, '\0'));
         v1::GetRelationBatchResponse out;
         grpc::ClientContext c;
         return stub.GetRelationBatch(&c, r, &out);
       }},
      {"batch with ragged bytes", C::INVALID_ARGUMENT, "ids.data: 7 bytes",
       [](auto*, auto& stub, auto&, auto& s) {
         v1::GetRelationBatchRequest r;
         r.set_session_id(s);
         r.set_relation(v1::RELATION_VERTEX_STAR);
         r.mutable_ids()->set_dtype(v1::DATA_TYPE_INT64);
         r.mutable_ids()->add_shape(1);
         r.mutable_ids()->set_data(std::string(7, '\0'));
         v1::GetRelationBatchResponse out;
         grpc::ClientContext c;
         return stub.GetRelationBatch(&c, r, &out);
       }},
      {"unknown algorithm", C::INVALID_ARGUMENT, "algorithm",
       [](auto*, auto& stub, auto&, auto& s) {
         v1::RunJobRequest r;
         r.set_session_id(s);
         grpc::ClientContext c;
         auto reader = stub.RunJob(&c, r);
         v1::RunJobResponse m;
         while (reader->Read(&m)) {
         }
         return reader->Finish();
       }},
      {"unknown algorithm parameter", C::INVALID_ARGUMENT, "unknown parameter 'speed'",
       [](auto*, auto& stub, auto&, auto& s) {
         v1::RunJobRequest r;
         r.set_session_id(s);
         r.set_algorithm(v1::ALGORITHM_MORSE_SMALE);
         (*r.mutable_parameters())["speed"] = "fast";
         grpc::ClientContext c;
         auto reader = stub.RunJob(&c, r);
         v1::RunJobResponse m;
         while (reader->Read(&m)) {
         }
         return reader->Finish();
       }},
      {"bad boundary rule", C::INVALID_ARGUMENT, "boundary_rule: unknown value 'maybe'",
       [](auto*, auto& stub, auto&, auto& s) {
         v1::RunJobRequest r;
         r.set_session_id(s);
         r.set_algorithm(v1::ALGORITHM_CRITICAL_POINTS);
         (*r.mutable_parameters())["boundary_rule"] = "maybe";
         grpc::ClientContext c;
         auto reader = stub.RunJob(&c, r);
         v1::RunJobResponse m;
         while (reader->Read(&m)) {
         }
         return reader->Finish();
       }},
      {"unknown job", C::NOT_FOUND, "job-x",
       [](auto*, auto& stub, auto&, auto&) {
         v1::CancelJobRequest r;
         r.set_job_id("job-x");
         v1::CancelJobResponse out;
         grpc::ClientContext c;
         return stub.CancelJob(&c, r, &out);
       }},
      {"upload: chunk before header", C::INVALID_ARGUMENT, "first message",
       [](auto*, auto& stub, auto&, auto&) {
         v1::UploadMeshResponse out;
         grpc::ClientContext c;
         auto w = stub.UploadMesh(&c, &out);
         v1::UploadMeshRequest m;
         m.set_chunk("abc");
         w->Write(m);
         w->WritesDone();
         return w->Finish();
       }},
      {"upload: truncated", C::INVALID_ARGUMENT, "truncated",
       [](auto* t, auto&, auto&, auto&) {
         TinyUpload u;
         return static_cast<BadInputTest*>(t)->Upload(u.header, {u.bytes.substr(0, 50)});
       }},
      {"upload: too many bytes", C::INVALID_ARGUMENT, "more than the",
       [](auto* t, auto&, auto&, auto&) {
         TinyUpload u;
         return static_cast<BadInputTest*>(t)->Upload(u.header, {u.bytes + "extra"});
       }},
      {"upload: checksum mismatch", C::DATA_LOSS, "corrupted upload",
       [](auto* t, auto&, auto&, auto&) {
         TinyUpload u;
         u.bytes[3] ^= 1;
         return static_cast<BadInputTest*>(t)->Upload(u.header, {u.bytes});
       }},
      {"upload: wrong points dtype", C::INVALID_ARGUMENT, "header.points_dtype: DATA_TYPE_INT8",
       [](auto* t, auto&, auto&, auto&) {
         TinyUpload u;
         u.header.set_points_dtype(v1::DATA_TYPE_INT8);
         return static_cast<BadInputTest*>(t)->Upload(u.header, {u.bytes});
       }},
      {"upload: zero tetrahedra", C::INVALID_ARGUMENT, "header.num_tetrahedra: 0",
       [](auto* t, auto&, auto&, auto&) {
         TinyUpload u;
         u.header.set_num_tetrahedra(0);
         return static_cast<BadInputTest*>(t)->Upload(u.header, {u.bytes});
       }},
      {"upload: vertex id out of range", C::OUT_OF_RANGE, "vertex id 9",
       [](auto* t, auto&, auto&, auto&) {
         TinyUpload u(1.0, 9);
         return static_cast<BadInputTest*>(t)->Upload(u.header, {u.bytes});
       }},
      {"upload: repeated vertex", C::INVALID_ARGUMENT, "repeats vertex 2",
       [](auto* t, auto&, auto&, auto&) {
         TinyUpload u(1.0, 2);
         return static_cast<BadInputTest*>(t)->Upload(u.header, {u.bytes});
       }},
      {"upload: NaN scalars refused at session open", C::INVALID_ARGUMENT, "non-finite value nan",
       [](auto*, auto& stub, auto&, auto&) {
         TinyUpload u(std::nan(""));
         v1::UploadMeshResponse out;
         grpc::ClientContext c;
         auto w = stub.UploadMesh(&c, &out);
         v1::UploadMeshRequest h;
         *h.mutable_header() = u.header;
         w->Write(h);
         v1::UploadMeshRequest m;
         m.set_chunk(u.bytes);
         w->Write(m);
         w->WritesDone();
         grpc::Status s = w->Finish();
         if (!s.ok()) return s;
         v1::OpenSessionRequest open;
         open.set_mesh_id(out.mesh().mesh_id());
         v1::OpenSessionResponse opened;
         grpc::ClientContext c2;
         return stub.OpenSession(&c2, open, &opened);
       }},
      {"message over the size limit", C::RESOURCE_EXHAUSTED, "",
       [](auto*, auto& stub, auto&, auto& s) {
         v1::GetRelationBatchRequest r;
         r.set_session_id(s);
         r.set_relation(v1::RELATION_VERTEX_STAR);
         r.mutable_ids()->set_dtype(v1::DATA_TYPE_INT64);
         r.mutable_ids()->set_data(std::string(size_t(65) << 20, '\0'));
         v1::GetRelationBatchResponse out;
         grpc::ClientContext c;
         return stub.GetRelationBatch(&c, r, &out);
       }},
  };
  ASSERT_GE(cases.size(), 25u);
  for (const Case& c : cases) {
    SCOPED_TRACE(c.name);
    const grpc::Status s = c.call(this, *stub_, mesh, session);
    EXPECT_EQ(s.error_code(), c.code) << s.error_message();
    EXPECT_NE(s.error_message().find(c.message), std::string::npos) << s.error_message();
    // Still serving, the same session included.
    EXPECT_TRUE(Relation(session, v1::RELATION_VERTEX_STAR, 3).ok());
  }
}

}  // namespace
}  // namespace actopo::service
