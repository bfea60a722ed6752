// Fields into a loaded mesh (AddFields, DeleteField) and jobs over several fields, through a
// real server: a field added behaves as one loaded with the mesh, a job over a list gives each
// field what a job on it alone gives, and diagram-distance's matrices equal the distances
// computed directly.
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>

#include "gmock/gmock.h"
#include "gtest/gtest.h"
#include "nlohmann/json.hpp"
#include "server/algorithms/digest.h"
#include "server/algorithms/persistence_diagram.h"
#include "server/algorithms/vertex_order.h"
#include "server/core/explicit_structure.h"
#include "server/core/partition.h"
#include "server/core/testing/status.h"
#include "server/io/test_data.h"
#include "server/io/vtk_reader.h"
#include "server/results/series.h"
#include "server/service/testing/service_fixture.h"
#include "tests/testing/skip.h"

namespace actopo::service {
namespace {

using ::testing::HasSubstr;
using testing::JobRun;
using testing::RunJob;
using testing::ServiceTest;

// jittered:8's fields: "scalar" and "height".
constexpr char kSample[] = "jittered:8";

template <class T>
std::string Bytes(const std::vector<T>& values) {
  return std::string(reinterpret_cast<const char*>(values.data()), values.size() * sizeof(T));
}

struct NewField {
  std::string name;
  v1::DataType dtype = v1::DATA_TYPE_FLOAT64;
  std::string bytes;
  std::optional<double> time;
};

NewField Float64(std::string name, const std::vector<double>& values,
                 std::optional<double> time = std::nullopt) {
  return {std::move(name), v1::DATA_TYPE_FLOAT64, Bytes(values), time};
}

class FieldsTest : public ServiceTest {
 protected:
  // AddFields with the fields' bytes in chunks of `chunk`; `sha256` "" checks nothing, "auto"
  // the right digest, "last" the right digest after the chunks (header.sha256_last), "last:D"
  // digest D after them, anything else is sent as it is.
  grpc::Status AddFields(const std::string& mesh_id, const std::vector<NewField>& fields,
                         v1::AddFieldsResponse* response, size_t chunk = 1000,
                         const std::string& sha256 = "auto", int64_t drop_bytes = 0) {
    auto context = Context();
    auto writer = stub_->AddFields(context.get(), response);
    v1::AddFieldsRequest header;
    header.mutable_header()->set_mesh_id(mesh_id);
    std::string data;
    for (const NewField& f : fields) {
      v1::UploadField* u = header.mutable_header()->add_fields();
      u->set_name(f.name);
      u->set_dtype(f.dtype);
      if (f.time) u->set_time(*f.time);
      data += f.bytes;
    }
    std::string last;
    if (sha256.starts_with("last")) {
      header.mutable_header()->set_sha256_last(true);
      last = sha256 == "last" ? Sha256Hex(data) : sha256.substr(5);
    } else {
      header.mutable_header()->set_sha256(sha256 == "auto" ? Sha256Hex(data) : sha256);
    }
    data.resize(data.size() - size_t(drop_bytes));
    bool writing = writer->Write(header);
    for (size_t at = 0; writing && at < data.size(); at += chunk) {
      v1::AddFieldsRequest piece;
      piece.set_chunk(data.substr(at, chunk));
      writing = writer->Write(piece);
    }
    if (writing && !last.empty()) {
      v1::AddFieldsRequest digest;
      digest.set_sha256(last);
      writer->Write(digest);
    }
    writer->WritesDone();
    return writer->Finish();
  }

  v1::MeshInfo GetMesh(const std::string& mesh_id) {
    v1::GetMeshRequest request;
    request.set_mesh_id(mesh_id);
    v1::GetMeshResponse response;
    EXPECT_TRUE(stub_->GetMesh(Context().get(), request, &response).ok());
    return response.mesh();
  }

  std::vector<std::string> FieldNames(const std::string& mesh_id) {
    std::vector<std::string> names;
    const v1::MeshInfo mesh = GetMesh(mesh_id);
    for (const v1::FieldInfo& f : mesh.fields()) names.push_back(f.name());
    return names;
  }

  std::string OpenOn(const std::string& mesh_id, const std::string& field,
                     v1::Structure structure = v1::STRUCTURE_COMPACT, int consumers = 1) {
    v1::OpenSessionRequest request;
    request.set_mesh_id(mesh_id);
    request.set_scalar_field(field);
    request.set_structure(structure);
    request.mutable_engine()->set_consumers(consumers);
    v1::OpenSessionResponse response;
    const grpc::Status s = stub_->OpenSession(Context().get(), request, &response);
    EXPECT_TRUE(s.ok()) << s.error_message();
    return response.session().session_id();
  }

  JobRun Job(const std::string& session, v1::Algorithm algorithm,
             const std::vector<std::string>& fields = {}, bool arrays = false,
             std::map<std::string, std::string> parameters = {}) {
    v1::RunJobRequest request;
    request.set_session_id(session);
    request.set_algorithm(algorithm);
    request.set_digests(true);
    request.set_include_arrays(arrays);
    for (const std::string& f : fields) request.add_fields(f);
    for (const auto& [k, v] : parameters) (*request.mutable_parameters())[k] = v;
    auto context = Context();
    return RunJob(*stub_, context.get(), request);
  }

  // The summary a job ended with, as JSON text.
  static std::string Summary(const JobRun& run) {
    for (const v1::RunJobResponse& m : run.messages) {
      if (m.has_summary()) return m.summary().result().DebugString();
    }
    return "";
  }
};

TEST_F(FieldsTest, TheDigestMayFollowTheChunks) {
  const Mesh sample = OkValue(io::MakeSample(kSample));
  const std::string mesh_id = LoadSample(kSample);
  v1::AddFieldsResponse added;
  // Chunks of many sizes: each is decoded while the next arrives.
  for (const size_t chunk : {size_t(13), size_t(4096), size_t(1) << 20}) {
    const std::string name = "copy" + std::to_string(chunk);
    const grpc::Status s =
        AddFields(mesh_id, {Float64(name, sample.point_fields[0].values)}, &added, chunk, "last");
    ASSERT_TRUE(s.ok()) << s.error_message();
    const v1::FieldInfo& info = added.mesh().fields(added.mesh().fields_size() - 1);
    EXPECT_EQ(info.name(), name);
    EXPECT_EQ(info.min(), *std::min_element(sample.point_fields[0].values.begin(),
                                            sample.point_fields[0].values.end()));
  }
  const std::string session = OpenOn(mesh_id, "scalar");
  const std::string copied = OpenOn(mesh_id, "copy13");
  EXPECT_EQ(Summary(Job(session, v1::ALGORITHM_CRITICAL_POINTS)),
            Summary(Job(copied, v1::ALGORITHM_CRITICAL_POINTS)));
}

TEST_F(FieldsTest, AnAddedFieldBehavesAsALoadedOne) {
  const Mesh sample = OkValue(io::MakeSample(kSample));
  const std::vector<double>& scalar = sample.point_fields[0].values;
  std::vector<double> twice(scalar);
  for (double& x : twice) x *= 2;
  std::vector<float> narrow(scalar.begin(), scalar.end());
  const std::string mesh_id = LoadSample(kSample);
  v1::AddFieldsResponse added;
  const grpc::Status s = AddFields(mesh_id,
                                   {Float64("twice", twice, 30.0),
                                    {"narrow", v1::DATA_TYPE_FLOAT32, Bytes(narrow), std::nullopt}},
                                   &added, /*chunk=*/777);
  ASSERT_TRUE(s.ok()) << s.error_message();
  ASSERT_EQ(added.mesh().fields_size(), 4);
  const v1::FieldInfo& info = added.mesh().fields(2);
  EXPECT_EQ(info.name(), "twice");
  EXPECT_EQ(info.dtype(), v1::DATA_TYPE_FLOAT64);
  EXPECT_EQ(info.min(), *std::min_element(twice.begin(), twice.end()));
  EXPECT_EQ(info.max(), *std::max_element(twice.begin(), twice.end()));
  EXPECT_TRUE(info.has_time());
  EXPECT_EQ(info.time(), 30.0);
  EXPECT_EQ(added.mesh().fields(3).dtype(), v1::DATA_TYPE_FLOAT32);
  EXPECT_FALSE(added.mesh().fields(3).has_time());
  EXPECT_EQ(FieldNames(mesh_id), (std::vector<std::string>{"scalar", "height", "twice", "narrow"}));

  // Twice the field orders the vertices the same way: the same critical points and pairs.
  for (const v1::Algorithm a : {v1::ALGORITHM_CRITICAL_POINTS, v1::ALGORITHM_PERSISTENCE_DIAGRAM}) {
    const JobRun on_scalar = Job(OpenOn(mesh_id, "scalar"), a);
    const JobRun on_twice = Job(OpenOn(mesh_id, "twice"), a);
    ASSERT_TRUE(on_twice.status.ok()) << on_twice.status.error_message();
    const auto digest = [](const JobRun& run, const std::string& key) {
      for (const v1::RunJobResponse& m : run.messages) {
        if (m.has_summary()) return m.summary().result().fields().at(key).string_value();
      }
      return std::string();
    };
    const std::string key = a == v1::ALGORITHM_CRITICAL_POINTS ? "vertices_sha256" : "pairs_sha256";
    EXPECT_FALSE(digest(on_scalar, key).empty());
    EXPECT_EQ(digest(on_twice, key), digest(on_scalar, key));
  }
}

TEST_F(FieldsTest, BadFieldsAreRefusedNamingWhatIsWrongAndAddNothing) {
  const std::string mesh_id = LoadSample(kSample);
  const int64_t n = GetMesh(mesh_id).vertices();
  const std::vector<double> ok(size_t(n), 1.5);
  std::vector<double> nan = ok;
  nan[7] = std::nan("");
  struct Case {
    std::string what;
    std::string mesh_id;
    std::vector<NewField> fields;
    grpc::StatusCode code;
    std::string message;
    std::string sha256 = "auto";
    int64_t drop_bytes = 0;
  };
  const std::vector<Case> cases = {
      {"unknown mesh", "mesh-nope", {Float64("f", ok)}, grpc::NOT_FOUND, "mesh_id: no mesh"},
      {"name taken",
       mesh_id,
       {Float64("height", ok)},
       grpc::ALREADY_EXISTS,
       "header.fields[0].name: mesh '" + mesh_id + "' has a field 'height' already"},
      {"repeated",
       mesh_id,
       {Float64("f", ok), Float64("f", ok)},
       grpc::INVALID_ARGUMENT,
       "header.fields[1].name: 'f' is announced twice"},
      {"integers",
       mesh_id,
       {{"f", v1::DATA_TYPE_INT32, Bytes(std::vector<int32_t>(n))}},
       grpc::INVALID_ARGUMENT,
       "header.fields[0].dtype: DATA_TYPE_INT32 is not FLOAT32"},
      {"not finite",
       mesh_id,
       {Float64("f", ok), Float64("g", nan)},
       grpc::INVALID_ARGUMENT,
       "fields[1] 'g': vertex 7 has value nan"},
      {"too few values",
       mesh_id,
       {Float64("f", std::vector<double>(size_t(n) - 1, 2.0))},
       grpc::INVALID_ARGUMENT,
       "the stream ended after"},
      {"too many values",
       mesh_id,
       {Float64("f", std::vector<double>(size_t(n) + 1, 2.0))},
       grpc::INVALID_ARGUMENT,
       "received more than the"},
      {"truncated",
       mesh_id,
       {Float64("f", ok)},
       grpc::INVALID_ARGUMENT,
       "the stream ended after",
       "auto",
       5},
      {"corrupted",
       mesh_id,
       {Float64("f", ok)},
       grpc::DATA_LOSS,
       "header.sha256: the values hash",
       std::string(64, 'a')},
      {"corrupted, digest last",
       mesh_id,
       {Float64("f", ok)},
       grpc::DATA_LOSS,
       "sha256: the values hash",
       "last:" + std::string(64, 'a')},
      {"digest last, malformed",
       mesh_id,
       {Float64("f", ok)},
       grpc::INVALID_ARGUMENT,
       "sha256: expected 64 lowercase hex digits",
       "last:abc"},
  };
  const std::string session = OpenOn(mesh_id, "height");
  const std::string before = Summary(Job(session, v1::ALGORITHM_CRITICAL_POINTS));
  for (const Case& c : cases) {
    v1::AddFieldsResponse response;
    const grpc::Status s = AddFields(c.mesh_id, c.fields, &response, 1000, c.sha256, c.drop_bytes);
    EXPECT_EQ(s.error_code(), c.code) << c.what << ": " << s.error_message();
    EXPECT_THAT(s.error_message(), HasSubstr(c.message)) << c.what;
    EXPECT_EQ(FieldNames(mesh_id), (std::vector<std::string>{"scalar", "height"})) << c.what;
  }
  // The mesh and its sessions did not notice.
  EXPECT_EQ(Summary(Job(session, v1::ALGORITHM_CRITICAL_POINTS)), before);
}

TEST_F(FieldsTest, FieldsBeyondTheMemoryBudgetAreRefusedBeforeTheirBytes) {
  options_.memory_budget_bytes = int64_t(40) << 20;
  StartServer();
  const std::string mesh_id = LoadSample("jittered:20", 500);
  const int64_t n = GetMesh(mesh_id).vertices();
  // Each field takes 8 bytes per vertex: a few hundred of them exceed 40 MiB.
  std::vector<NewField> many;
  for (int k = 0; k < 800; ++k) many.push_back(Float64("f" + std::to_string(k), {}));
  auto context = Context();
  v1::AddFieldsResponse response;
  auto writer = stub_->AddFields(context.get(), &response);
  v1::AddFieldsRequest header;
  header.mutable_header()->set_mesh_id(mesh_id);
  for (const NewField& f : many) {
    v1::UploadField* u = header.mutable_header()->add_fields();
    u->set_name(f.name);
    u->set_dtype(v1::DATA_TYPE_FLOAT64);
  }
  writer->Write(header);
  writer->WritesDone();
  const grpc::Status s = writer->Finish();
  EXPECT_EQ(s.error_code(), grpc::RESOURCE_EXHAUSTED) << s.error_message();
  EXPECT_THAT(s.error_message(), HasSubstr("of mesh '" + mesh_id + "'"));
  EXPECT_GT(n, 0);
  EXPECT_EQ(FieldNames(mesh_id).size(), 2u);
  // What was reserved for the refused call came back: one field still fits.
  ASSERT_TRUE(
      AddFields(mesh_id, {Float64("one", std::vector<double>(size_t(n), 1.0))}, &response).ok());
}

TEST_F(FieldsTest, ADeletedFieldStaysWithTheSessionsReadingIt) {
  const std::string mesh_id = LoadSample(kSample);
  const std::string session = OpenOn(mesh_id, "scalar", v1::STRUCTURE_ACTOPO);
  const std::string before = Summary(Job(session, v1::ALGORITHM_PERSISTENCE_DIAGRAM));
  v1::DeleteFieldRequest request;
  request.set_mesh_id(mesh_id);
  request.set_name("scalar");
  v1::DeleteFieldResponse response;
  ASSERT_TRUE(stub_->DeleteField(Context().get(), request, &response).ok());
  ASSERT_EQ(response.mesh().fields_size(), 1);
  EXPECT_EQ(response.mesh().fields(0).name(), "height");
  EXPECT_EQ(Summary(Job(session, v1::ALGORITHM_PERSISTENCE_DIAGRAM)), before);
  // Gone for everyone else: a new session, a job's list, a second delete.
  v1::OpenSessionRequest open;
  open.set_mesh_id(mesh_id);
  open.set_scalar_field("scalar");
  v1::OpenSessionResponse opened;
  const grpc::Status refused = stub_->OpenSession(Context().get(), open, &opened);
  EXPECT_EQ(refused.error_code(), grpc::NOT_FOUND);
  EXPECT_THAT(refused.error_message(), HasSubstr("scalar field 'scalar' not found"));
  const JobRun listed = Job(session, v1::ALGORITHM_CRITICAL_POINTS, {"height", "scalar"});
  EXPECT_EQ(listed.status.error_code(), grpc::NOT_FOUND);
  EXPECT_THAT(listed.status.error_message(), HasSubstr("fields[1]: scalar field 'scalar'"));
  const grpc::Status again = stub_->DeleteField(Context().get(), request, &response);
  EXPECT_EQ(again.error_code(), grpc::NOT_FOUND);
  EXPECT_THAT(again.error_message(), HasSubstr("name: the mesh has no field 'scalar'"));
  request.set_mesh_id("mesh-nope");
  EXPECT_EQ(stub_->DeleteField(Context().get(), request, &response).error_code(), grpc::NOT_FOUND);
}

TEST_F(FieldsTest, AJobOverFieldsGivesEachWhatAJobOnItAloneGives) {
  const std::string mesh_id = LoadSample(kSample);
  const std::vector<std::string> fields = {"height", "scalar"};
  for (const v1::Structure kind :
       {v1::STRUCTURE_EXPLICIT, v1::STRUCTURE_COMPACT, v1::STRUCTURE_ACTOPO}) {
    for (const v1::Algorithm a : {v1::ALGORITHM_CRITICAL_POINTS, v1::ALGORITHM_MORSE_SMALE,
                                  v1::ALGORITHM_PERSISTENCE_DIAGRAM, v1::ALGORITHM_MERGE_TREE,
                                  v1::ALGORITHM_CONTOUR_TREE}) {
      // The list decides, not the session's field ("scalar", second in the list).
      const std::string session = OpenOn(mesh_id, "scalar", kind, 2);
      const JobRun run = Job(session, a, fields, /*arrays=*/true);
      ASSERT_TRUE(run.status.ok()) << run.status.error_message();
      std::vector<std::string> done;
      double reached = 0;
      for (const v1::RunJobResponse& m : run.messages) {
        // The list's progress: field k's run fills [k / n, (k + 1) / n], never going back.
        if (m.has_progress() && m.progress().phase() == "run") {
          const double k = double(done.size()), n = double(fields.size());
          EXPECT_GE(m.progress().fraction(), std::max(k / n, reached) - 1e-12);
          EXPECT_LE(m.progress().fraction(), (k + 1) / n + 1e-12);
          reached = m.progress().fraction();
        }
        if (m.has_chunk()) {
          EXPECT_EQ(m.chunk().field(), done.size() < fields.size() ? fields[done.size()] : "");
        }
        if (!m.has_field()) continue;
        EXPECT_EQ(m.field().index(), int(done.size()));
        done.push_back(m.field().field());
        const JobRun alone = Job(OpenOn(mesh_id, m.field().field()), a);
        EXPECT_EQ(m.field().result().DebugString(), Summary(alone))
            << m.field().field() << " " << v1::Algorithm_Name(a);
        EXPECT_GT(m.field().run_seconds(), 0);
      }
      EXPECT_EQ(done, fields);
      EXPECT_THAT(Summary(run), HasSubstr("\"height\""));
      // One job however many fields.
      v1::GetSessionStatsRequest stats_request;
      stats_request.set_session_id(session);
      v1::GetSessionStatsResponse stats;
      ASSERT_TRUE(stub_->GetSessionStats(Context().get(), stats_request, &stats).ok());
      EXPECT_EQ(stats.jobs().count(), 1);
      EXPECT_TRUE(run.messages.back().has_stats());
    }
  }
}

TEST_F(FieldsTest, DiagramDistanceEqualsTheDistancesOfTheFieldsDiagrams) {
  const Mesh sample = OkValue(io::MakeSample(kSample));
  const std::string mesh_id = LoadSample(kSample);
  std::vector<double> bent(sample.point_fields[0].values);
  for (size_t v = 0; v < bent.size(); ++v) bent[v] += 0.3 * std::sin(double(v));
  v1::AddFieldsResponse added;
  ASSERT_TRUE(AddFields(mesh_id, {Float64("bent", bent)}, &added).ok());
  const std::vector<std::string> fields = {"scalar", "height", "bent"};
  const JobRun run = Job(OpenOn(mesh_id, "scalar", v1::STRUCTURE_ACTOPO, 2),
                         v1::ALGORITHM_DIAGRAM_DISTANCE, fields, false, {{"p", "1"}});
  ASSERT_TRUE(run.status.ok()) << run.status.error_message();
  google::protobuf::Struct summary;
  for (const v1::RunJobResponse& m : run.messages) {
    if (m.has_summary()) summary = m.summary().result();
  }
  // The reference: each field's diagram on an explicit structure, compared directly.
  auto topology =
      OkValue(Topology::Build(sample, OctreeBlocks(sample.points, {.bucket_capacity = 50})));
  auto structure = OkValue(ExplicitStructure::Build(topology, {}));
  std::vector<diagrams::Diagram> expected;
  for (const std::string& name : fields) {
    const std::vector<double>& values = name == "bent" ? bent : sample.FindField(name)->values;
    const auto diagram =
        OkValue(RunPersistenceDiagram(*structure, VertexOrder(*topology, values), values, {}));
    expected.push_back(diagrams::ToDiagram(diagram));
  }
  const auto& w = summary.fields().at("wasserstein").list_value();
  const auto& b = summary.fields().at("bottleneck").list_value();
  ASSERT_EQ(w.values_size(), 3);
  EXPECT_EQ(summary.fields().at("p").number_value(), 1);
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) {
      const diagrams::Distance d = diagrams::ComputeDistance(expected[i], expected[j], {.p = 1});
      EXPECT_NEAR(w.values(i).list_value().values(j).number_value(), d.wasserstein,
                  1e-12 * std::max(1.0, d.wasserstein));
      EXPECT_EQ(b.values(i).list_value().values(j).number_value(), d.bottleneck);
    }
  }
  EXPECT_GT(w.values(0).list_value().values(2).number_value(), 0);
}

TEST_F(FieldsTest, TrackingFollowsThePairsOfConsecutiveFields) {
  const Mesh sample = OkValue(io::MakeSample(kSample));
  const std::string mesh_id = LoadSample(kSample);
  // Three steps of a field drifting in time.
  std::vector<NewField> steps;
  std::vector<std::vector<double>> values;
  for (int t = 0; t < 3; ++t) {
    std::vector<double> v(sample.point_fields[0].values);
    for (size_t k = 0; k < v.size(); ++k) v[k] += 0.05 * t * std::cos(double(k) + t);
    steps.push_back(Float64("t" + std::to_string(t), v, double(t)));
    values.push_back(std::move(v));
  }
  v1::AddFieldsResponse added;
  ASSERT_TRUE(AddFields(mesh_id, steps, &added).ok());
  const JobRun run = Job(OpenOn(mesh_id, "scalar", v1::STRUCTURE_COMPACT, 2),
                         v1::ALGORITHM_TRACKING, {"t0", "t1", "t2"}, /*arrays=*/true);
  ASSERT_TRUE(run.status.ok()) << run.status.error_message();
  google::protobuf::Struct summary;
  std::map<std::string, int64_t> elements;  // tracking/<array> -> values
  for (const v1::RunJobResponse& m : run.messages) {
    if (m.has_summary()) summary = m.summary().result();
    if (m.has_chunk() && m.chunk().field().empty()) {
      int64_t n = 1;
      for (int64_t d : m.chunk().array().shape()) n *= d;
      elements[m.chunk().array().name()] = n;
    }
  }
  auto topology =
      OkValue(Topology::Build(sample, OctreeBlocks(sample.points, {.bucket_capacity = 50})));
  auto structure = OkValue(ExplicitStructure::Build(topology, {}));
  std::vector<diagrams::Diagram> expected;
  for (const std::vector<double>& v : values) {
    expected.push_back(diagrams::ToDiagram(
        OkValue(RunPersistenceDiagram(*structure, VertexOrder(*topology, v), v, {}))));
  }
  const auto& step = summary.fields().at("step_wasserstein").list_value();
  ASSERT_EQ(step.values_size(), 2);
  for (int t = 0; t < 2; ++t) {
    const double w = diagrams::ComputeDistance(expected[t], expected[t + 1], {}).wasserstein;
    EXPECT_NEAR(step.values(t).number_value(), w, 1e-12 * std::max(1.0, w));
  }
  const int64_t links = int64_t(summary.fields().at("links").number_value());
  EXPECT_GT(links, 0);
  EXPECT_EQ(elements["tracking/Cost"], links);
  EXPECT_EQ(elements["tracking/ConnectedComponentId"], links);
  EXPECT_EQ(elements["tracking/Offsets"], links + 1);
  EXPECT_EQ(elements["tracking/Points"], 3 * elements["tracking/TimeStep"]);
  EXPECT_EQ(elements["tracking/VertexId"], elements["tracking/TimeStep"]);
}

TEST_F(FieldsTest, ASeriesLoadsFromAParaViewCollectionAsOneMesh) {
  namespace fs = std::filesystem;
  const fs::path shared = io::testing::DataDir();
  if (!fs::is_directory(shared / "isabel_series_s2")) {
    ACTOPO_SKIP() << "the shared data folder " << shared << " is not there";
  }
  fs::copy(shared / "isabel_series_s2", data_dir_ / "isabel");
  v1::LoadMeshRequest load;
  load.set_path("isabel/isabel_series.pvd");
  v1::LoadMeshResponse loaded;
  const grpc::Status s = stub_->LoadMesh(Context().get(), load, &loaded);
  ASSERT_TRUE(s.ok()) << s.error_message();
  ASSERT_EQ(loaded.mesh().fields_size(), 4);
  for (int k = 0; k < 4; ++k) {
    EXPECT_EQ(loaded.mesh().fields(k).name(), "velocityMag_" + std::to_string(k));
    EXPECT_EQ(loaded.mesh().fields(k).time(), 2 + k);
  }
  // Every member's diagram is TTK's (expected-ttk-series.json, members 02 to 05).
  std::ifstream expected_file(shared / "expected-ttk-series.json");
  const auto expected = nlohmann::json::parse(expected_file)["isabel_series_s2_tet.vtu"];
  v1::RunJobRequest request;
  request.set_session_id(OpenOn(loaded.mesh().mesh_id(), "", v1::STRUCTURE_ACTOPO, 2));
  request.set_algorithm(v1::ALGORITHM_PERSISTENCE_DIAGRAM);
  request.set_all_fields(true);
  request.set_digests(true);
  auto context = Context();
  const JobRun run = RunJob(*stub_, context.get(), request);
  ASSERT_TRUE(run.status.ok()) << run.status.error_message();
  int members = 0;
  for (const v1::RunJobResponse& m : run.messages) {
    if (!m.has_field()) continue;
    const std::string member = "velocityMag_0" + std::to_string(2 + m.field().index());
    EXPECT_EQ(m.field().result().fields().at("pairs_sha256").string_value(),
              expected[member]["upstream"]["persistence_diagram"]["pairs_sha256"])
        << member;
    ++members;
  }
  EXPECT_EQ(members, 4);
  // A collection may list only files under the data directory.
  std::ofstream(data_dir_ / "escape.pvd")
      << "<VTKFile><Collection><DataSet file=\"../outside.vtu\"/></Collection></VTKFile>";
  load.set_path("escape.pvd");
  const grpc::Status escape = stub_->LoadMesh(Context().get(), load, &loaded);
  EXPECT_EQ(escape.error_code(), grpc::INVALID_ARGUMENT);
  EXPECT_THAT(escape.error_message(), HasSubstr("outside the server's data directory"));
}

TEST_F(FieldsTest, ASeriesLoadsFromAListOfFilesAsOneMesh) {
  namespace fs = std::filesystem;
  const fs::path shared = io::testing::DataDir();
  if (!fs::is_directory(shared / "isabel_series_s2")) {
    ACTOPO_SKIP() << "the shared data folder " << shared << " is not there";
  }
  fs::copy(shared / "isabel_series_s2", data_dir_ / "isabel");
  fs::copy(shared / "fertility_tet.vtu", data_dir_ / "fertility_tet.vtu");
  const auto load = [&](const std::vector<std::string>& paths, const std::vector<double>& times,
                        v1::LoadMeshResponse* loaded) {
    v1::LoadMeshRequest request;
    request.mutable_files();  // set, even when empty
    for (const std::string& path : paths) request.mutable_files()->add_paths(path);
    for (double time : times) request.mutable_files()->add_times(time);
    return stub_->LoadMesh(Context().get(), request, loaded);
  };
  v1::LoadMeshResponse loaded;
  const grpc::Status s = load(
      {"isabel/isabel_04_s2_tet.vtu", "isabel/isabel_02_s2_tet.vtu", "isabel/isabel_05_s2_tet.vtu"},
      {4.5, 2.5, 5.5}, &loaded);
  ASSERT_TRUE(s.ok()) << s.error_message();
  ASSERT_EQ(loaded.mesh().fields_size(), 3);
  const double times[] = {4.5, 2.5, 5.5};
  for (int k = 0; k < 3; ++k) {
    EXPECT_EQ(loaded.mesh().fields(k).name(), "velocityMag_" + std::to_string(k));
    EXPECT_EQ(loaded.mesh().fields(k).time(), times[k]);
  }
  EXPECT_EQ(loaded.mesh().name(), "isabel_04_s2_tet.vtu +2 files");
  // Each step's field is that file's: its diagram is TTK's for that member.
  std::ifstream expected_file(shared / "expected-ttk-series.json");
  const auto expected = nlohmann::json::parse(expected_file)["isabel_series_s2_tet.vtu"];
  v1::RunJobRequest request;
  request.set_session_id(OpenOn(loaded.mesh().mesh_id(), "", v1::STRUCTURE_COMPACT, 1));
  request.set_algorithm(v1::ALGORITHM_PERSISTENCE_DIAGRAM);
  request.add_fields("velocityMag_1");
  request.set_digests(true);
  auto context = Context();
  const JobRun run = RunJob(*stub_, context.get(), request);
  ASSERT_TRUE(run.status.ok()) << run.status.error_message();
  std::string pairs;
  for (const v1::RunJobResponse& m : run.messages) {
    if (m.has_field()) pairs = m.field().result().fields().at("pairs_sha256").string_value();
  }
  EXPECT_EQ(pairs, expected["velocityMag_02"]["upstream"]["persistence_diagram"]["pairs_sha256"]);

  struct Case {
    std::vector<std::string> paths;
    std::vector<double> times;
    grpc::StatusCode code;
    std::string message;
  };
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const std::vector<Case> cases = {
      {{}, {}, grpc::INVALID_ARGUMENT, "files.paths: empty"},
      {{"isabel/isabel_02_s2_tet.vtu"},
       {1, 2},
       grpc::INVALID_ARGUMENT,
       "files.times: 2 values for 1 paths"},
      {{"isabel/isabel_02_s2_tet.vtu", "isabel/nope.vtu"},
       {},
       grpc::NOT_FOUND,
       "files.paths[1]: 'isabel/nope.vtu' not found in the data directory"},
      {{"isabel/isabel_02_s2_tet.vtu", "../x.vtu"},
       {},
       grpc::INVALID_ARGUMENT,
       "files.paths[1]: '../x.vtu' is outside the server's data directory"},
      {{"isabel/isabel_series.pvd"},
       {},
       grpc::INVALID_ARGUMENT,
       "files.paths[0]: 'isabel/isabel_series.pvd' is a collection"},
      {{"isabel/isabel_02_s2_tet.vtu", "isabel/isabel_03_s2_tet.vtu"},
       {0, nan},
       grpc::INVALID_ARGUMENT,
       "files.times[1]: nan is not finite"},
      {{"isabel/isabel_02_s2_tet.vtu", "fertility_tet.vtu"},
       {},
       grpc::INVALID_ARGUMENT,
       "files: step 1: fertility_tet.vtu: has 14570 points, not 51597"},
  };
  for (const Case& c : cases) {
    const grpc::Status status = load(c.paths, c.times, &loaded);
    EXPECT_EQ(status.error_code(), c.code) << c.message << ": " << status.error_message();
    EXPECT_THAT(status.error_message(), HasSubstr(c.message));
  }
}

TEST_F(FieldsTest, ADownloadGivesTheMeshAsGivenWithTheFieldsAskedFor) {
  namespace fs = std::filesystem;
  const fs::path file = fs::path(io::testing::DataDir()) / "fertility_tet.vtu";
  if (!fs::exists(file)) ACTOPO_SKIP() << file << " is not there";
  fs::copy(file, data_dir_ / "fertility_tet.vtu");
  const Mesh given = OkValue(io::ReadMesh(file.string()));
  v1::LoadMeshRequest load;
  load.set_path("fertility_tet.vtu");
  v1::LoadMeshResponse loaded;
  ASSERT_TRUE(stub_->LoadMesh(Context().get(), load, &loaded).ok());
  const std::string mesh_id = loaded.mesh().mesh_id();
  std::vector<float> narrow(given.points.size() / 3);
  for (size_t v = 0; v < narrow.size(); ++v) narrow[v] = float(given.points[3 * v]) * 0.5f;
  v1::AddFieldsResponse added;
  ASSERT_TRUE(
      AddFields(mesh_id, {{"narrow", v1::DATA_TYPE_FLOAT32, Bytes(narrow), 7.0}}, &added).ok());

  const auto download = [&](const std::vector<std::string>& fields, bool all,
                            v1::UploadMeshHeader* header, std::string* bytes) {
    v1::DownloadMeshRequest request;
    request.set_mesh_id(mesh_id);
    for (const std::string& f : fields) request.add_fields(f);
    request.set_all_fields(all);
    auto context = Context();
    auto reader = stub_->DownloadMesh(context.get(), request);
    v1::DownloadMeshResponse message;
    int chunks = 0;
    while (reader->Read(&message)) {
      if (message.has_header()) *header = message.header();
      if (message.has_chunk()) {
        *bytes += message.chunk();
        ++chunks;
      }
    }
    const grpc::Status status = reader->Finish();
    EXPECT_TRUE(!status.ok() || chunks >= 2);  // points, tetrahedra: at least one chunk each
    return status;
  };
  v1::UploadMeshHeader header;
  std::string bytes;
  const grpc::Status s = download({"narrow", "height"}, false, &header, &bytes);
  ASSERT_TRUE(s.ok()) << s.error_message();
  const int64_t n = given.num_vertices(), t = given.num_tetrahedra();
  EXPECT_EQ(header.num_vertices(), n);
  EXPECT_EQ(header.num_tetrahedra(), t);
  EXPECT_EQ(header.points_dtype(), v1::DATA_TYPE_FLOAT64);
  EXPECT_EQ(header.tetrahedra_dtype(), v1::DATA_TYPE_INT32);
  ASSERT_EQ(header.fields_size(), 2);
  EXPECT_EQ(header.fields(0).name(), "narrow");
  EXPECT_EQ(header.fields(0).dtype(), v1::DATA_TYPE_FLOAT32);
  EXPECT_EQ(header.fields(0).time(), 7.0);
  EXPECT_EQ(header.fields(1).dtype(), v1::DATA_TYPE_FLOAT64);
  ASSERT_EQ(bytes.size(), size_t(24 * n + 16 * t + 4 * n + 8 * n));
  const char* at = bytes.data();
  EXPECT_EQ(std::memcmp(at, given.points.data(), size_t(24 * n)), 0);
  at += 24 * n;
  std::vector<int32_t> tetrahedra(size_t(4 * t));
  std::memcpy(tetrahedra.data(), at, size_t(16 * t));
  at += 16 * t;
  // Every tetrahedron as given: the same vertices in the same order.
  EXPECT_TRUE(std::equal(tetrahedra.begin(), tetrahedra.end(), given.tetrahedra.begin()));
  EXPECT_EQ(std::memcmp(at, narrow.data(), size_t(4 * n)), 0);
  at += 4 * n;
  EXPECT_EQ(std::memcmp(at, given.FindField("height")->values.data(), size_t(8 * n)), 0);

  bytes.clear();
  ASSERT_TRUE(download({}, true, &header, &bytes).ok());
  EXPECT_EQ(header.fields_size(), 3);  // eigenfunction4, height, narrow

  struct Case {
    std::string mesh;
    std::vector<std::string> fields;
    bool all;
    grpc::StatusCode code;
    std::string message;
  };
  const std::vector<Case> cases = {
      {"mesh-nope", {}, false, grpc::NOT_FOUND, "mesh_id: no mesh"},
      {mesh_id,
       {"height", "nope"},
       false,
       grpc::NOT_FOUND,
       "fields[1]: point field 'nope' not found; point fields: 'eigenfunction4', 'height', "
       "'narrow'"},
      {mesh_id,
       {"height", "height"},
       false,
       grpc::INVALID_ARGUMENT,
       "fields[1]: 'height' is listed twice"},
      {mesh_id,
       {"height"},
       true,
       grpc::INVALID_ARGUMENT,
       "fields: give the fields or all_fields, not both"},
  };
  for (const Case& c : cases) {
    v1::DownloadMeshRequest request;
    request.set_mesh_id(c.mesh);
    for (const std::string& f : c.fields) request.add_fields(f);
    request.set_all_fields(c.all);
    auto context = Context();
    auto reader = stub_->DownloadMesh(context.get(), request);
    v1::DownloadMeshResponse message;
    EXPECT_FALSE(reader->Read(&message)) << c.message;
    const grpc::Status status = reader->Finish();
    EXPECT_EQ(status.error_code(), c.code) << c.message << ": " << status.error_message();
    EXPECT_THAT(status.error_message(), HasSubstr(c.message));
  }
}

TEST_F(FieldsTest, ADownloadedFieldKeepsItsTypeUnlessItsValuesDoNotFit) {
  std::ofstream(data_dir_ / "unsigned.vtu") << R"(<?xml version="1.0"?>
<VTKFile type="UnstructuredGrid" version="0.1" byte_order="LittleEndian">
<UnstructuredGrid><Piece NumberOfPoints="5" NumberOfCells="2">
<PointData>
<DataArray type="UInt32" Name="small" format="ascii">7 1 3 0 2</DataArray>
<DataArray type="UInt32" Name="large" format="ascii">4000000000 1 3 0 2</DataArray>
<DataArray type="Float32" Name="narrow" format="ascii">0.5 0.25 1.5 -2 3.125</DataArray>
</PointData>
<Points><DataArray type="Float64" NumberOfComponents="3" format="ascii">
0 0 0  1 0 0  0 1 0  0 0 1  1 1 1</DataArray></Points>
<Cells>
<DataArray type="Int64" Name="connectivity" format="ascii">3 1 0 2  2 4 1 3</DataArray>
<DataArray type="Int64" Name="offsets" format="ascii">4 8</DataArray>
<DataArray type="UInt8" Name="types" format="ascii">10 10</DataArray>
</Cells>
</Piece></UnstructuredGrid></VTKFile>
)";
  v1::LoadMeshRequest load;
  load.set_path("unsigned.vtu");
  v1::LoadMeshResponse loaded;
  const grpc::Status s = stub_->LoadMesh(Context().get(), load, &loaded);
  ASSERT_TRUE(s.ok()) << s.error_message();
  v1::DownloadMeshRequest request;
  request.set_mesh_id(loaded.mesh().mesh_id());
  request.set_all_fields(true);
  auto context = Context();
  auto reader = stub_->DownloadMesh(context.get(), request);
  v1::DownloadMeshResponse message;
  v1::UploadMeshHeader header;
  std::string bytes;
  while (reader->Read(&message)) {
    if (message.has_header()) header = message.header();
    bytes += message.chunk();
  }
  ASSERT_TRUE(reader->Finish().ok());
  ASSERT_EQ(header.fields_size(), 3);
  EXPECT_EQ(header.fields(0).dtype(), v1::DATA_TYPE_INT32);  // its values fit
  EXPECT_EQ(header.fields(1).dtype(), v1::DATA_TYPE_INT64);  // 4e9 does not
  EXPECT_EQ(header.fields(2).dtype(), v1::DATA_TYPE_FLOAT32);
  const size_t large = size_t(5 * 24 + 2 * 16 + 5 * 4);
  ASSERT_EQ(bytes.size(), large + 5 * 8 + 5 * 4);
  int64_t first = 0;
  std::memcpy(&first, bytes.data() + large, 8);
  EXPECT_EQ(first, 4000000000);
}

TEST_F(FieldsTest, BadFieldListsAreNamed) {
  const std::string mesh_id = LoadSample(kSample);
  const std::string session = OpenOn(mesh_id, "scalar");
  struct Case {
    v1::Algorithm algorithm;
    std::vector<std::string> fields;
    bool all = false;
    grpc::StatusCode code;
    std::string message;
  };
  const std::vector<Case> cases = {
      {v1::ALGORITHM_DIAGRAM_DISTANCE,
       {},
       false,
       grpc::INVALID_ARGUMENT,
       "fields: diagram-distance compares at least two fields"},
      {v1::ALGORITHM_DIAGRAM_DISTANCE,
       {"scalar"},
       false,
       grpc::INVALID_ARGUMENT,
       "compares at least two fields; give them in fields (or all_fields), not 1"},
      {v1::ALGORITHM_CRITICAL_POINTS,
       {"scalar", "nope"},
       false,
       grpc::NOT_FOUND,
       "fields[1]: scalar field 'nope' not found; point fields: 'scalar', 'height'"},
      {v1::ALGORITHM_CRITICAL_POINTS,
       {"scalar", "scalar"},
       false,
       grpc::INVALID_ARGUMENT,
       "fields[1]: 'scalar' is listed twice"},
      {v1::ALGORITHM_CRITICAL_POINTS,
       {"scalar"},
       true,
       grpc::INVALID_ARGUMENT,
       "fields: give fields or all_fields, not both"},
      {v1::ALGORITHM_TOPO_RELATIONS,
       {"scalar"},
       false,
       grpc::INVALID_ARGUMENT,
       "fields: topo-relations reads no scalar field"},
      {v1::ALGORITHM_DIAGRAM_DISTANCE,
       {"scalar", "height"},
       false,
       grpc::INVALID_ARGUMENT,
       "parameters.p: 0.5 is not a Wasserstein order"},
      {v1::ALGORITHM_DIAGRAM_DISTANCE,
       {"scalar", "height"},
       false,
       grpc::INVALID_ARGUMENT,
       "parameters.matching: 0,2 is outside the list of 2 fields"},
  };
  for (const Case& c : cases) {
    v1::RunJobRequest request;
    request.set_session_id(session);
    request.set_algorithm(c.algorithm);
    for (const std::string& f : c.fields) request.add_fields(f);
    request.set_all_fields(c.all);
    if (c.message.find("parameters.p:") != std::string::npos) {
      (*request.mutable_parameters())["p"] = "0.5";
    }
    if (c.message.find("parameters.matching") != std::string::npos) {
      (*request.mutable_parameters())["matching"] = "0,2";
    }
    auto context = Context();
    const JobRun run = RunJob(*stub_, context.get(), request);
    EXPECT_EQ(run.status.error_code(), c.code) << c.message << ": " << run.status.error_message();
    EXPECT_THAT(run.status.error_message(), HasSubstr(c.message));
  }
  // all_fields takes every floating-point field, in the mesh's order.
  v1::RunJobRequest all;
  all.set_session_id(session);
  all.set_algorithm(v1::ALGORITHM_DIAGRAM_DISTANCE);
  all.set_all_fields(true);
  auto context = Context();
  const JobRun run = RunJob(*stub_, context.get(), all);
  ASSERT_TRUE(run.status.ok()) << run.status.error_message();
  EXPECT_THAT(Summary(run), HasSubstr("\"scalar\""));
}

}  // namespace
}  // namespace actopo::service
