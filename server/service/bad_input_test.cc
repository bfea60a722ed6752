// A corpus of bad requests and hostile meshes, each answered with its expected code and a message
// naming the offending field or value, while the server keeps serving a good request after each.
#include <cmath>
#include <fstream>
#include <functional>
#include <tuple>

#include "server/algorithms/digest.h"
#include "server/io/test_data.h"
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
  // Each case gets its code and a message with its text, and the server still answers on
  // `session` after it.
  void ExpectEach(const std::vector<Case>& cases, const std::string& mesh,
                  const std::string& session) {
    for (const Case& c : cases) {
      SCOPED_TRACE(c.name);
      const grpc::Status s = c.call(this, *stub_, mesh, session);
      EXPECT_EQ(s.error_code(), c.code) << s.error_message();
      EXPECT_NE(s.error_message().find(c.message), std::string::npos) << s.error_message();
      EXPECT_TRUE(Relation(session, v1::RELATION_VERTEX_STAR, 3).ok());
    }
  }
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

// A RunJob call read to its end: its final status.
grpc::Status RunToEnd(v1::TopologyService::Stub& stub, const v1::RunJobRequest& request) {
  grpc::ClientContext c;
  auto reader = stub.RunJob(&c, request);
  v1::RunJobResponse m;
  while (reader->Read(&m)) {
  }
  return reader->Finish();
}

using C = grpc::StatusCode;

// Loading by path or sample.
std::vector<Case> LoadCases() {
  return {
      {"path escaping the data dir", C::INVALID_ARGUMENT, "outside the server's data directory",
       [](auto* t, auto&, auto&, auto&) {
         return static_cast<BadInputTest*>(t)->Load("../../etc/passwd");
       }},
      {"absolute path", C::INVALID_ARGUMENT, "outside",
       [](auto* t, auto&, auto&, auto&) {
         return static_cast<BadInputTest*>(t)->Load("/etc/passwd");
       }},
      {"missing file", C::NOT_FOUND, "nope.vtu",
       [](auto* t, auto&, auto&, auto&) {
         return static_cast<BadInputTest*>(t)->Load("nope.vtu");
       }},
      {"unknown extension", C::INVALID_ARGUMENT, ".txt",
       [](auto* t, auto&, auto&, auto&) {
         return static_cast<BadInputTest*>(t)->Load("notamesh.txt");
       }},
      {"corrupt vtu", C::INVALID_ARGUMENT, "corrupt.vtu",
       [](auto* t, auto&, auto&, auto&) {
         return static_cast<BadInputTest*>(t)->Load("corrupt.vtu");
       }},
      {"empty path", C::INVALID_ARGUMENT, "path",
       [](auto* t, auto&, auto&, auto&) { return static_cast<BadInputTest*>(t)->Load(""); }},
      {"a sample as a path", C::NOT_FOUND,
       "path: 'jittered:5' not found in the data directory; it names a built-in sample: load it "
       "as sample:jittered:5",
       [](auto* t, auto&, auto&, auto&) {
         return static_cast<BadInputTest*>(t)->Load("jittered:5");
       }},
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
  };
}

// Opening sessions.
std::vector<Case> SessionCases() {
  return {
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
  };
}

// Relation queries, one simplex or a batch.
std::vector<Case> RelationCases() {
  return {
      {"unknown session", C::NOT_FOUND, "session-guess",
       [](auto* t, auto&, auto&, auto&) {
         return static_cast<BadInputTest*>(t)->Relation("session-guess", v1::RELATION_VERTEX_STAR,
                                                        0);
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
  };
}

// Jobs and their parameters.
std::vector<Case> JobCases() {
  return {
      {"unknown algorithm", C::INVALID_ARGUMENT, "algorithm",
       [](auto*, auto& stub, auto&, auto& s) {
         v1::RunJobRequest r;
         r.set_session_id(s);
         return RunToEnd(stub, r);
       }},
      {"unknown algorithm parameter", C::INVALID_ARGUMENT, "unknown parameter 'speed'",
       [](auto*, auto& stub, auto&, auto& s) {
         v1::RunJobRequest r;
         r.set_session_id(s);
         r.set_algorithm(v1::ALGORITHM_MORSE_SMALE);
         (*r.mutable_parameters())["speed"] = "fast";
         return RunToEnd(stub, r);
       }},
      {"bad boundary rule", C::INVALID_ARGUMENT, "boundary_rule: unknown value 'maybe'",
       [](auto*, auto& stub, auto&, auto& s) {
         v1::RunJobRequest r;
         r.set_session_id(s);
         r.set_algorithm(v1::ALGORITHM_CRITICAL_POINTS);
         (*r.mutable_parameters())["boundary_rule"] = "maybe";
         return RunToEnd(stub, r);
       }},
      {"bad diagram embedding", C::INVALID_ARGUMENT,
       "parameters.embedding: unknown value 'sideways'; available: diagram, domain",
       [](auto*, auto& stub, auto&, auto& s) {
         v1::RunJobRequest r;
         r.set_session_id(s);
         r.set_algorithm(v1::ALGORITHM_PERSISTENCE_DIAGRAM);
         (*r.mutable_parameters())["embedding"] = "sideways";
         return RunToEnd(stub, r);
       }},
      {"unknown merge tree type", C::INVALID_ARGUMENT,
       "parameters.tree: unknown value 'contour'; available: join, split",
       [](auto*, auto& stub, auto&, auto& s) {
         v1::RunJobRequest r;
         r.set_session_id(s);
         r.set_algorithm(v1::ALGORITHM_MERGE_TREE);
         (*r.mutable_parameters())["tree"] = "contour";
         return RunToEnd(stub, r);
       }},
      {"tree type given to the contour tree", C::INVALID_ARGUMENT,
       "parameters: unknown parameter 'tree' for contour-tree",
       [](auto*, auto& stub, auto&, auto& s) {
         v1::RunJobRequest r;
         r.set_session_id(s);
         r.set_algorithm(v1::ALGORITHM_CONTOUR_TREE);
         (*r.mutable_parameters())["tree"] = "join";
         return RunToEnd(stub, r);
       }},
      {"threshold not a number", C::INVALID_ARGUMENT,
       "parameters.relative_threshold: 'lots' is not a number",
       [](auto*, auto& stub, auto&, auto& s) {
         v1::RunJobRequest r;
         r.set_session_id(s);
         r.set_algorithm(v1::ALGORITHM_TOPOLOGICAL_SIMPLIFICATION);
         (*r.mutable_parameters())["relative_threshold"] = "lots";
         return RunToEnd(stub, r);
       }},
      {"relative threshold above 1", C::INVALID_ARGUMENT,
       "parameters.relative_threshold: threshold: 1.5 is not a fraction",
       [](auto*, auto& stub, auto&, auto& s) {
         v1::RunJobRequest r;
         r.set_session_id(s);
         r.set_algorithm(v1::ALGORITHM_MORSE_SMALE);
         (*r.mutable_parameters())["relative_threshold"] = "1.5";
         return RunToEnd(stub, r);
       }},
      {"unknown simplification backend", C::INVALID_ARGUMENT,
       "parameters.backend: unknown value 'fast'; available: lts, legacy",
       [](auto*, auto& stub, auto&, auto& s) {
         v1::RunJobRequest r;
         r.set_session_id(s);
         r.set_algorithm(v1::ALGORITHM_TOPOLOGICAL_SIMPLIFICATION);
         (*r.mutable_parameters())["backend"] = "fast";
         return RunToEnd(stub, r);
       }},
      {"backend without a threshold", C::INVALID_ARGUMENT,
       "parameters.backend: morse-smale simplifies only with",
       [](auto*, auto& stub, auto&, auto& s) {
         v1::RunJobRequest r;
         r.set_session_id(s);
         r.set_algorithm(v1::ALGORITHM_MORSE_SMALE);
         (*r.mutable_parameters())["backend"] = "legacy";
         return RunToEnd(stub, r);
       }},
      {"two thresholds", C::INVALID_ARGUMENT,
       "give persistence_threshold or relative_threshold, not both",
       [](auto*, auto& stub, auto&, auto& s) {
         v1::RunJobRequest r;
         r.set_session_id(s);
         r.set_algorithm(v1::ALGORITHM_TOPOLOGICAL_SIMPLIFICATION);
         (*r.mutable_parameters())["relative_threshold"] = "0.1";
         (*r.mutable_parameters())["persistence_threshold"] = "2";
         return RunToEnd(stub, r);
       }},
      {"unknown job", C::NOT_FOUND, "job-x",
       [](auto*, auto& stub, auto&, auto&) {
         v1::CancelJobRequest r;
         r.set_job_id("job-x");
         v1::CancelJobResponse out;
         grpc::ClientContext c;
         return stub.CancelJob(&c, r, &out);
       }},
  };
}

// Uploads, and what an uploaded mesh may hold.
std::vector<Case> UploadCases() {
  return {
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
}

TEST_F(BadInputTest, EveryCaseGetsItsCodeAndTheServerKeepsServing) {
  std::filesystem::copy_file("/etc/hostname", data_dir_ / "notamesh.txt");
  {
    std::ofstream corrupt(data_dir_ / "corrupt.vtu");
    corrupt << "<?xml version=\"1.0\"?><VTKFile type=\"UnstructuredGrid\"><garbage";
  }
  const std::string mesh = LoadSample("jittered:5");
  const std::string session = Open(mesh, v1::STRUCTURE_ACTOPO);
  std::vector<Case> cases;
  for (auto* group : {LoadCases, SessionCases, RelationCases, JobCases, UploadCases}) {
    for (Case& c : group()) cases.push_back(std::move(c));
  }
  ASSERT_GE(cases.size(), 25u);
  ExpectEach(cases, mesh, session);
}

// A legacy VTK file: points (x y z per line), cells (one "n v0 v1 ..." per line) and their types.
std::string Legacy(const std::vector<std::string>& points, const std::vector<std::string>& cells,
                   const std::vector<int>& types) {
  std::string text = "# vtk DataFile Version 3.0\nhostile\nASCII\nDATASET UNSTRUCTURED_GRID\n";
  text += "POINTS " + std::to_string(points.size()) + " double\n";
  for (const std::string& p : points) text += p + "\n";
  size_t size = 0;
  for (const std::string& c : cells) size += 1 + std::count(c.begin(), c.end(), ' ');
  text += "CELLS " + std::to_string(cells.size()) + " " + std::to_string(size) + "\n";
  for (const std::string& c : cells) text += c + "\n";
  text += "CELL_TYPES " + std::to_string(types.size()) + "\n";
  for (int t : types) text += std::to_string(t) + "\n";
  text += "POINT_DATA " + std::to_string(points.size()) +
          "\nSCALARS s double 1\n"
          "LOOKUP_TABLE default\n";
  for (size_t i = 0; i < points.size(); ++i) text += std::to_string(i) + " ";
  return text + "\n";
}

// A VTK XML unstructured grid of tetrahedra with raw appended data: any bit pattern goes in.
std::string RawVtu(const std::vector<double>& points, const std::vector<int64_t>& tetrahedra) {
  std::string data;
  std::vector<size_t> offsets;
  const auto append = [&](const void* bytes, size_t n) {
    offsets.push_back(data.size());
    const uint32_t size = uint32_t(n);
    data.append(reinterpret_cast<const char*>(&size), 4);
    data.append(static_cast<const char*>(bytes), n);
  };
  const size_t cells = tetrahedra.size() / 4;
  std::vector<int64_t> ends(cells);
  for (size_t c = 0; c < cells; ++c) ends[c] = int64_t(4 * (c + 1));
  const std::vector<uint8_t> types(cells, 10);
  append(points.data(), points.size() * 8);
  append(tetrahedra.data(), tetrahedra.size() * 8);
  append(ends.data(), ends.size() * 8);
  append(types.data(), types.size());
  const auto array = [&](const char* type, const char* name, int k, size_t offset) {
    return std::string("<DataArray type=\"") + type + "\" Name=\"" + name +
           "\" NumberOfComponents=\"" + std::to_string(k) + "\" format=\"appended\" offset=\"" +
           std::to_string(offset) + "\"/>";
  };
  return "<?xml version=\"1.0\"?><VTKFile type=\"UnstructuredGrid\" version=\"1.0\" "
         "byte_order=\"LittleEndian\" header_type=\"UInt32\"><UnstructuredGrid><Piece "
         "NumberOfPoints=\"" +
         std::to_string(points.size() / 3) + "\" NumberOfCells=\"" + std::to_string(cells) +
         "\"><Points>" + array("Float64", "Points", 3, offsets[0]) + "</Points><Cells>" +
         array("Int64", "connectivity", 1, offsets[1]) + array("Int64", "offsets", 1, offsets[2]) +
         array("UInt8", "types", 1, offsets[3]) +
         "</Cells></Piece></UnstructuredGrid><AppendedData encoding=\"raw\">_" + data +
         "</AppendedData></VTKFile>";
}

const std::vector<std::string> kCorners = {"0 0 0", "1 0 0", "0 1 0", "0 0 1", "1 1 1"};
constexpr int kTet = 10, kTriangle = 5;

grpc::Status OpenWith(v1::TopologyService::Stub& stub, const std::string& mesh,
                      const std::function<void(v1::OpenSessionRequest&)>& set) {
  v1::OpenSessionRequest r;
  r.set_mesh_id(mesh);
  set(r);
  v1::OpenSessionResponse out;
  grpc::ClientContext c;
  return stub.OpenSession(&c, r, &out);
}

grpc::Status BatchWith(v1::TopologyService::Stub& stub, const std::string& session,
                       const std::function<void(v1::GetRelationBatchRequest&)>& set) {
  v1::GetRelationBatchRequest r;
  r.set_session_id(session);
  r.set_relation(v1::RELATION_VERTEX_STAR);
  set(r);
  v1::GetRelationBatchResponse out;
  grpc::ClientContext c;
  return stub.GetRelationBatch(&c, r, &out);
}

grpc::Status LoadWith(v1::TopologyService::Stub& stub,
                      const std::function<void(v1::LoadMeshRequest&)>& set) {
  v1::LoadMeshRequest r;
  set(r);
  v1::LoadMeshResponse out;
  grpc::ClientContext c;
  return stub.LoadMesh(&c, r, &out);
}

void SetInt64s(v1::Array* a, const std::vector<int64_t>& values, std::vector<int64_t> shape) {
  a->set_dtype(v1::DATA_TYPE_INT64);
  for (int64_t n : shape) a->add_shape(n);
  a->set_data(std::string(reinterpret_cast<const char*>(values.data()), values.size() * 8));
}

// A case that loads `path` from the data directory.
std::function<grpc::Status(ServiceTest*, v1::TopologyService::Stub&, const std::string&,
                           const std::string&)>
LoadPath(std::string path) {
  return [path](auto* t, auto&, auto&, auto&) { return static_cast<BadInputTest*>(t)->Load(path); };
}

// Hostile mesh files (written by HostileMeshesAndMoreRequests).
std::vector<Case> HostileFileCases() {
  return {
      {"file: NaN coordinate", C::INVALID_ARGUMENT, "vertex 1 has a non-finite coordinate x = nan",
       LoadPath("nan.vtu")},
      {"file: infinite coordinate", C::INVALID_ARGUMENT,
       "vertex 2 has a non-finite coordinate y = inf", LoadPath("inf.vtu")},
      {"file: mixed cell types", C::INVALID_ARGUMENT, "only tetrahedral", LoadPath("mixed.vtk")},
      {"file: triangles only", C::INVALID_ARGUMENT, "only tetrahedral", LoadPath("flat.vtk")},
      {"file: vertex id out of range", C::INVALID_ARGUMENT, "badid.vtk", LoadPath("badid.vtk")},
      {"file: repeated vertex", C::INVALID_ARGUMENT, "repeats vertex 1", LoadPath("repeat.vtk")},
      {"file: truncated", C::INVALID_ARGUMENT, "truncated.vtk", LoadPath("truncated.vtk")},
      {"file: huge counts in the header", C::RESOURCE_EXHAUSTED, "by its header",
       LoadPath("claims.vtu")},
      {"file: empty", C::INVALID_ARGUMENT, "empty.vtu", LoadPath("empty.vtu")},
      {"file: legacy POINTS cut short (VTK crashes)", C::INVALID_ARGUMENT,
       "cut_short.vtk: VTK's reader crashed on this file", LoadPath("cut_short.vtk")},
      {"file: compressed block size 0 (VTK crashes)", C::INVALID_ARGUMENT,
       "block_size_zero.vtu: VTK's reader crashed on this file", LoadPath("block_size_zero.vtu")},
      {"file: a directory", C::INVALID_ARGUMENT, "directory", LoadPath("folder.vtu")},
      {"file: symlink out of the data dir", C::INVALID_ARGUMENT, "outside", LoadPath("escape.vtk")},
      {"file: dot-dot inside the path", C::INVALID_ARGUMENT, "outside",
       LoadPath("sub/../../x.vtu")},
  };
}

// Partition options and samples.
std::vector<Case> PartitionAndSampleCases() {
  return {
      {"partition: negative block size", C::INVALID_ARGUMENT, "block size: -5",
       [](auto*, auto& stub, auto&, auto&) {
         return LoadWith(stub, [](auto& r) {
           r.set_sample("jittered:4");
           r.mutable_partition()->set_block_size(-5);
         });
       }},
      {"partition: missing label field", C::NOT_FOUND, "point field 'labels' not found",
       [](auto*, auto& stub, auto&, auto&) {
         return LoadWith(stub, [](auto& r) {
           r.set_sample("jittered:4");
           r.mutable_partition()->set_block_label_field("labels");
         });
       }},
      {"partition: labels that are not integers", C::INVALID_ARGUMENT, "not a 32-bit integer",
       [](auto*, auto& stub, auto&, auto&) {
         return LoadWith(stub, [](auto& r) {
           r.set_sample("jittered:4");
           r.mutable_partition()->set_block_label_field("scalar");
         });
       }},
      {"sample: N out of range", C::INVALID_ARGUMENT, "N = 1 is outside",
       [](auto*, auto& stub, auto&, auto&) {
         return LoadWith(stub, [](auto& r) { r.set_sample("jittered:1"); });
       }},
      {"sample: N not a number", C::INVALID_ARGUMENT, "N 'big' is not an integer",
       [](auto*, auto& stub, auto&, auto&) {
         return LoadWith(stub, [](auto& r) { r.set_sample("wavelet:big"); });
       }},
      {"sample: too big for the budget", C::RESOURCE_EXHAUSTED, "sample 'wavelet:512'",
       [](auto*, auto& stub, auto&, auto&) {
         return LoadWith(stub, [](auto& r) { r.set_sample("wavelet:512"); });
       }},
  };
}

// Engine options of a session.
std::vector<Case> EngineCases() {
  return {
      {"session: consumers over the range", C::INVALID_ARGUMENT, "engine.consumers: 1000",
       [](auto*, auto& stub, auto& m, auto&) {
         return OpenWith(stub, m, [](auto& r) { r.mutable_engine()->set_consumers(1000); });
       }},
      {"session: prefetch out of the enum", C::INVALID_ARGUMENT, "engine.prefetch: 17",
       [](auto*, auto& stub, auto& m, auto&) {
         return OpenWith(stub, m, [](auto& r) {
           r.mutable_engine()->set_prefetch(static_cast<v1::Prefetch>(17));
         });
       }},
      {"session: precompute out of the enum", C::INVALID_ARGUMENT, "engine.precompute: 9",
       [](auto*, auto& stub, auto& m, auto&) {
         return OpenWith(stub, m, [](auto& r) {
           r.mutable_engine()->set_precompute(static_cast<v1::Precompute>(9));
         });
       }},
      {"session: NaN buffer ratio", C::INVALID_ARGUMENT, "engine.buffer_ratio: nan",
       [](auto*, auto& stub, auto& m, auto&) {
         return OpenWith(stub, m,
                         [](auto& r) { r.mutable_engine()->set_buffer_ratio(std::nan("")); });
       }},
  };
}

// Batches and single relations.
std::vector<Case> BatchAndRelationCases() {
  return {
      {"batch: tuples of the wrong width", C::INVALID_ARGUMENT, "vertex_tuples.shape",
       [](auto*, auto& stub, auto&, auto& s) {
         return BatchWith(stub, s, [](auto& r) {
           r.set_relation(v1::RELATION_EDGE_STAR);
           SetInt64s(r.mutable_vertex_tuples(), {0, 1, 2}, {1, 3});
         });
       }},
      {"batch: ids and tuples both", C::INVALID_ARGUMENT, "set exactly one",
       [](auto*, auto& stub, auto&, auto& s) {
         return BatchWith(stub, s, [](auto& r) {
           SetInt64s(r.mutable_ids(), {0}, {1});
           SetInt64s(r.mutable_vertex_tuples(), {0}, {1, 1});
         });
       }},
      {"batch: neither ids nor tuples", C::INVALID_ARGUMENT, "set exactly one",
       [](auto*, auto& stub, auto&, auto& s) { return BatchWith(stub, s, [](auto&) {}); }},
      {"batch: a negative id", C::OUT_OF_RANGE, "ids[1]: vertex id -4",
       [](auto*, auto& stub, auto&, auto& s) {
         return BatchWith(stub, s, [](auto& r) { SetInt64s(r.mutable_ids(), {0, -4}, {2}); });
       }},
      // Found by fuzz/request_fuzzer: the extents' product overflowed int64 (UBSan).
      {"batch: a shape whose product overflows", C::INVALID_ARGUMENT,
       "vertex_tuples.data: 24 bytes for shape [7419881405664, 6176702, 3] of 8-byte values",
       [](auto*, auto& stub, auto&, auto& s) {
         return BatchWith(stub, s, [](auto& r) {
           SetInt64s(r.mutable_vertex_tuples(), {0, 1, 2}, {7419881405664, 6176702, 3});
         });
       }},
      {"batch: a shape with more values than its data", C::INVALID_ARGUMENT,
       "ids.data: 16 bytes for shape [4] of 8-byte values",
       [](auto*, auto& stub, auto&, auto& s) {
         return BatchWith(stub, s, [](auto& r) { SetInt64s(r.mutable_ids(), {0, 1}, {4}); });
       }},
      {"batch: over the batch limit", C::RESOURCE_EXHAUSTED, "batch limit",
       [](auto*, auto& stub, auto&, auto& s) {
         return BatchWith(stub, s, [](auto& r) {
           SetInt64s(r.mutable_ids(), std::vector<int64_t>((1 << 20) + 1, 0), {(1 << 20) + 1});
         });
       }},
      {"relation: simplex not set", C::INVALID_ARGUMENT, "simplex: set id or vertices",
       [](auto*, auto& stub, auto&, auto& s) {
         v1::GetRelationRequest q;
         q.set_session_id(s);
         q.set_relation(v1::RELATION_VERTEX_STAR);
         v1::GetRelationResponse out;
         grpc::ClientContext c;
         return stub.GetRelation(&c, q, &out);
       }},
      {"relation: edge id past the end", C::OUT_OF_RANGE, "edge id 100000",
       [](auto* t, auto&, auto&, auto& s) {
         return static_cast<BadInputTest*>(t)->Relation(s, v1::RELATION_EDGE_STAR, 100000);
       }},
      {"relation: triangle given as an edge tuple", C::INVALID_ARGUMENT,
       "a triangle has 3 vertices, got 4",
       [](auto* t, auto&, auto&, auto& s) {
         return static_cast<BadInputTest*>(t)->Tuple(s, v1::RELATION_TRIANGLE_EDGES, {0, 1, 2, 3});
       }},
  };
}

// Jobs, statistics, closing, deleting, deadlines.
std::vector<Case> OtherCallCases() {
  return {
      {"job: unknown session", C::NOT_FOUND, "session-none",
       [](auto*, auto& stub, auto&, auto&) {
         v1::RunJobRequest r;
         r.set_session_id("session-none");
         r.set_algorithm(v1::ALGORITHM_CRITICAL_POINTS);
         return RunToEnd(stub, r);
       }},
      {"job: algorithm out of the enum", C::INVALID_ARGUMENT, "algorithm: 99",
       [](auto*, auto& stub, auto&, auto& s) {
         v1::RunJobRequest r;
         r.set_session_id(s);
         r.set_algorithm(static_cast<v1::Algorithm>(99));
         return RunToEnd(stub, r);
       }},
      {"stats: unknown session", C::NOT_FOUND, "session-none",
       [](auto*, auto& stub, auto&, auto&) {
         v1::GetSessionStatsRequest r;
         r.set_session_id("session-none");
         v1::GetSessionStatsResponse out;
         grpc::ClientContext c;
         return stub.GetSessionStats(&c, r, &out);
       }},
      {"close: unknown session", C::NOT_FOUND, "session-none",
       [](auto*, auto& stub, auto&, auto&) {
         v1::CloseSessionRequest r;
         r.set_session_id("session-none");
         v1::CloseSessionResponse out;
         grpc::ClientContext c;
         return stub.CloseSession(&c, r, &out);
       }},
      {"delete: unknown mesh", C::NOT_FOUND, "mesh-none",
       [](auto*, auto& stub, auto&, auto&) {
         v1::DeleteMeshRequest r;
         r.set_mesh_id("mesh-none");
         v1::DeleteMeshResponse out;
         grpc::ClientContext c;
         return stub.DeleteMesh(&c, r, &out);
       }},
      {"a deadline already passed", C::DEADLINE_EXCEEDED, "",
       [](auto*, auto& stub, auto&, auto&) {
         grpc::ClientContext c;
         c.set_deadline(std::chrono::system_clock::now() - std::chrono::seconds(1));
         v1::GetServerInfoResponse out;
         return stub.GetServerInfo(&c, {}, &out);
       }},
  };
}

// Uploads: headers and their fields.
std::vector<Case> MoreUploadCases() {
  return {
      {"upload: nothing sent", C::INVALID_ARGUMENT, "the upload was empty",
       [](auto*, auto& stub, auto&, auto&) {
         v1::UploadMeshResponse out;
         grpc::ClientContext c;
         auto w = stub.UploadMesh(&c, &out);
         w->WritesDone();
         return w->Finish();
       }},
      {"upload: two headers", C::INVALID_ARGUMENT, "only one header",
       [](auto*, auto& stub, auto&, auto&) {
         TinyUpload u;
         v1::UploadMeshResponse out;
         grpc::ClientContext c;
         auto w = stub.UploadMesh(&c, &out);
         v1::UploadMeshRequest h;
         *h.mutable_header() = u.header;
         w->Write(h);
         w->Write(h);
         w->WritesDone();
         return w->Finish();
       }},
      {"upload: negative vertex count", C::INVALID_ARGUMENT, "header.num_vertices: -4",
       [](auto* t, auto&, auto&, auto&) {
         TinyUpload u;
         u.header.set_num_vertices(-4);
         return static_cast<BadInputTest*>(t)->Upload(u.header, {u.bytes});
       }},
      {"upload: huge counts", C::RESOURCE_EXHAUSTED, "uploading 2000000000 vertices",
       [](auto* t, auto&, auto&, auto&) {
         TinyUpload u;
         u.header.set_num_vertices(2000000000);
         u.header.set_num_tetrahedra(2000000000);
         return static_cast<BadInputTest*>(t)->Upload(u.header, {u.bytes});
       }},
      {"upload: field of a bad dtype", C::INVALID_ARGUMENT, "header.fields[0].dtype",
       [](auto* t, auto&, auto&, auto&) {
         TinyUpload u;
         u.header.mutable_fields(0)->set_dtype(v1::DATA_TYPE_UINT8);
         return static_cast<BadInputTest*>(t)->Upload(u.header, {u.bytes});
       }},
      {"upload: field without a name", C::INVALID_ARGUMENT, "header.fields[0].name: empty",
       [](auto* t, auto&, auto&, auto&) {
         TinyUpload u;
         u.header.mutable_fields(0)->set_name("");
         return static_cast<BadInputTest*>(t)->Upload(u.header, {u.bytes});
       }},
      {"upload: checksum of the wrong length", C::INVALID_ARGUMENT, "header.sha256",
       [](auto* t, auto&, auto&, auto&) {
         TinyUpload u;
         u.header.set_sha256("abc");
         return static_cast<BadInputTest*>(t)->Upload(u.header, {u.bytes});
       }},
      {"upload: infinite scalar refused at session open", C::INVALID_ARGUMENT, "non-finite",
       [](auto*, auto& stub, auto&, auto&) {
         TinyUpload u(INFINITY);
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
         return OpenWith(stub, out.mesh().mesh_id(), [](auto&) {});
       }},
  };
}

TEST_F(BadInputTest, HostileMeshesAndMoreRequests) {
  const auto write = [&](const std::string& name, const std::string& text) {
    std::ofstream(data_dir_ / name) << text;
  };
  // VTK's legacy ASCII reader rejects "nan" as a word: non-finite points come in binary XML.
  write("nan.vtu", RawVtu({0, 0, 0, std::nan(""), 0, 0, 0, 1, 0, 0, 0, 1}, {0, 1, 2, 3}));
  write("inf.vtu", RawVtu({0, 0, 0, 1, 0, 0, 0, INFINITY, 0, 0, 0, 1}, {0, 1, 2, 3}));
  write("mixed.vtk", Legacy(kCorners, {"4 0 1 2 3", "3 1 2 4"}, {kTet, kTriangle}));
  write("flat.vtk", Legacy(kCorners, {"3 0 1 2", "3 1 2 4"}, {kTriangle, kTriangle}));
  write("badid.vtk", Legacy(kCorners, {"4 0 1 2 99"}, {kTet}));
  write("repeat.vtk", Legacy(kCorners, {"4 0 1 1 3"}, {kTet}));
  write("truncated.vtk", Legacy(kCorners, {"4 0 1 2 3"}, {kTet}).substr(0, 150));
  write("claims.vtu",
        "<VTKFile type=\"UnstructuredGrid\"><UnstructuredGrid>"
        "<Piece NumberOfPoints=\"900000000\" NumberOfCells=\"5000000000\">");
  write("empty.vtu", "");
  // Files VTK's own readers crash on: read in a child process, they fail the load, not the
  // server.
  io::testing::WriteVtkCrashFiles(data_dir_, ACTOPO_SOURCE_DIR);
  std::filesystem::create_directories(data_dir_ / "folder.vtu");
  std::filesystem::create_symlink("/etc/passwd", data_dir_ / "escape.vtk");
  // Good enough to load, but degenerate: inverted, flat (coplanar) and duplicated tetrahedra and
  // coincident points. These are served, not refused: topology does not need volume.
  write("degenerate.vtk",
        Legacy({"0 0 0", "1 0 0", "0 1 0", "0 0 1", "1 1 0", "0 0 0"},
               {"4 0 2 1 3", "4 0 1 2 4", "4 0 1 2 3", "4 5 1 2 4"}, {kTet, kTet, kTet, kTet}));

  const std::string mesh = LoadSample("jittered:5");
  const std::string session = Open(mesh, v1::STRUCTURE_COMPACT);
  std::vector<Case> cases;
  for (auto* group : {HostileFileCases, PartitionAndSampleCases, EngineCases, BatchAndRelationCases,
                      OtherCallCases, MoreUploadCases}) {
    for (Case& c : group()) cases.push_back(std::move(c));
  }
  ASSERT_GE(cases.size(), 40u);
  ExpectEach(cases, mesh, session);
  // The degenerate mesh is served, and every algorithm runs on it.
  v1::LoadMeshRequest r;
  r.set_path("degenerate.vtk");
  v1::LoadMeshResponse loaded;
  ASSERT_TRUE(stub_->LoadMesh(Context().get(), r, &loaded).ok());
  const std::string degenerate = Open(loaded.mesh().mesh_id(), v1::STRUCTURE_ACTOPO);
  for (v1::Algorithm a : {v1::ALGORITHM_CRITICAL_POINTS, v1::ALGORITHM_DISCRETE_GRADIENT,
                          v1::ALGORITHM_MORSE_SMALE, v1::ALGORITHM_TOPO_RELATIONS}) {
    v1::RunJobRequest job;
    job.set_session_id(degenerate);
    job.set_algorithm(a);
    auto context = Context();
    auto reader = stub_->RunJob(context.get(), job);
    v1::RunJobResponse m;
    while (reader->Read(&m)) {
    }
    EXPECT_TRUE(reader->Finish().ok()) << v1::Algorithm_Name(a);
  }
}

}  // namespace
}  // namespace actopo::service
