// actopo-load: load generator for a running actopo-server. Reports unary relation-query latency
// (p50, p90, p99) with C concurrent clients, streamed and batched relation throughput, and the
// wall time of a job through the service (to compare with actopo-bench in process).
//
//   actopo-load --server 127.0.0.1:50051 --sample jittered:40 --clients 8 --seconds 5 --json
#include <grpcpp/grpcpp.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <iostream>
#include <random>
#include <thread>

#include "absl/strings/str_cat.h"
#include "actopo/v1/topology_service.grpc.pb.h"
#include "nlohmann/json.hpp"
#include "server/cmd/flags.h"

namespace {

namespace v1 = ::actopo::v1;
using Clock = std::chrono::steady_clock;
using Json = nlohmann::ordered_json;

struct Options {
  std::string server = "127.0.0.1:50051";
  std::string sample = "jittered:40";
  std::string structure = "actopo";
  std::string relation = "vertex_star";
  int clients = 1;
  double seconds = 3;
  int batch = 10000;
  std::string algorithm = "critical-points";
  bool json = false;
};

double Ms(Clock::duration d) { return std::chrono::duration<double, std::milli>(d).count(); }

double Percentile(std::vector<double>& v, double p) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  return v[std::min(v.size() - 1, size_t(p * v.size()))];
}

[[noreturn]] void Fail(const std::string& what, const grpc::Status& s) {
  std::cerr << "actopo-load: " << what << ": " << s.error_message() << "\n";
  std::exit(1);
}

v1::Relation RelationEnum(const std::string& name) {
  const std::string upper = "RELATION_" + [&] {
    std::string u = name;
    for (char& c : u) c = char(std::toupper(c));
    return u;
  }();
  v1::Relation r = v1::RELATION_UNSPECIFIED;
  if (!v1::Relation_Parse(upper, &r)) {
    std::cerr << "actopo-load: --relation: unknown relation '" << name << "'\n";
    std::exit(2);
  }
  return r;
}

}  // namespace

int main(int argc, char** argv) {
  Options o;
  actopo::FlagParser flags("actopo-load", "load generator for actopo-server");
  flags.Add("server", &o.server, "HOST:PORT");
  flags.Add("sample", &o.sample, "built-in sample to load");
  flags.Add("structure", &o.structure, "explicit, compact or actopo");
  flags.Add("relation", &o.relation, "relation for the queries");
  flags.Add("clients", &o.clients, "concurrent unary clients");
  flags.Add("seconds", &o.seconds, "duration of each phase");
  flags.Add("batch", &o.batch, "simplices per GetRelationBatch");
  flags.Add("algorithm", &o.algorithm, "algorithm for the job timing");
  flags.Add("json", &o.json, "print one JSON object");
  if (absl::Status s = flags.Parse(argc, argv); !s.ok()) {
    std::cerr << "actopo-load: " << s.message() << "\n";
    return 2;
  }
  if (flags.help_requested()) {
    std::cout << flags.Usage();
    return 0;
  }
  grpc::ChannelArguments args;
  args.SetMaxReceiveMessageSize(256 << 20);
  auto channel = grpc::CreateCustomChannel(o.server, grpc::InsecureChannelCredentials(), args);
  auto stub = v1::TopologyService::NewStub(channel);

  v1::LoadMeshRequest load;
  load.set_sample(o.sample);
  v1::LoadMeshResponse mesh;
  {
    grpc::ClientContext c;
    if (auto s = stub->LoadMesh(&c, load, &mesh); !s.ok()) Fail("LoadMesh", s);
  }
  v1::OpenSessionRequest open;
  open.set_mesh_id(mesh.mesh().mesh_id());
  open.set_structure(o.structure == "explicit"  ? v1::STRUCTURE_EXPLICIT
                     : o.structure == "compact" ? v1::STRUCTURE_COMPACT
                                                : v1::STRUCTURE_ACTOPO);
  v1::OpenSessionResponse session;
  {
    grpc::ClientContext c;
    if (auto s = stub->OpenSession(&c, open, &session); !s.ok()) Fail("OpenSession", s);
  }
  const std::string sid = session.session().session_id();
  const v1::Relation relation = RelationEnum(o.relation);
  const int64_t nv = mesh.mesh().vertices();

  // Unary latency with `clients` threads, each on its own channel.
  std::vector<std::vector<double>> latencies(o.clients);
  std::vector<std::thread> threads;
  const auto deadline = Clock::now() + std::chrono::duration<double>(o.seconds);
  for (int c = 0; c < o.clients; ++c) {
    threads.emplace_back([&, c] {
      auto own = v1::TopologyService::NewStub(
          grpc::CreateCustomChannel(o.server, grpc::InsecureChannelCredentials(), args));
      std::mt19937_64 rng(c);
      v1::GetRelationRequest q;
      q.set_session_id(sid);
      q.set_relation(relation);
      while (Clock::now() < deadline) {
        q.mutable_simplex()->set_id(int64_t(rng() % nv));
        v1::GetRelationResponse r;
        grpc::ClientContext ctx;
        const auto start = Clock::now();
        if (auto s = own->GetRelation(&ctx, q, &r); !s.ok()) Fail("GetRelation", s);
        latencies[c].push_back(Ms(Clock::now() - start));
      }
    });
  }
  for (auto& t : threads) t.join();
  std::vector<double> all;
  for (auto& l : latencies) all.insert(all.end(), l.begin(), l.end());
  const double unary_qps = all.size() / o.seconds;

  // Streamed: ids in order, one request per item, pipelined by a writer thread.
  int64_t streamed = 0;
  double stream_s = 0;
  {
    grpc::ClientContext c;
    auto stream = stub->StreamRelations(&c);
    const int64_t n = std::min<int64_t>(nv, 200000);
    const auto start = Clock::now();
    std::thread writer([&] {
      v1::StreamRelationsRequest q;
      q.set_session_id(sid);
      q.set_relation(relation);
      for (int64_t i = 0; i < n; ++i) {
        q.set_request_id(i);
        q.mutable_simplex()->set_id(i);
        if (!stream->Write(q)) break;
      }
      stream->WritesDone();
    });
    v1::StreamRelationsResponse r;
    while (stream->Read(&r)) ++streamed;
    writer.join();
    if (auto s = stream->Finish(); !s.ok()) Fail("StreamRelations", s);
    stream_s = std::chrono::duration<double>(Clock::now() - start).count();
  }

  // Batched: all vertices in batches.
  double batch_s = 0;
  int64_t batched = 0;
  {
    const auto start = Clock::now();
    for (int64_t first = 0; first < nv; first += o.batch) {
      const int64_t n = std::min<int64_t>(o.batch, nv - first);
      std::vector<int64_t> ids(n);
      for (int64_t i = 0; i < n; ++i) ids[i] = first + i;
      v1::GetRelationBatchRequest b;
      b.set_session_id(sid);
      b.set_relation(relation);
      b.mutable_ids()->set_dtype(v1::DATA_TYPE_INT64);
      b.mutable_ids()->add_shape(n);
      b.mutable_ids()->set_data(std::string(reinterpret_cast<const char*>(ids.data()), n * 8));
      v1::GetRelationBatchResponse out;
      grpc::ClientContext c;
      if (auto s = stub->GetRelationBatch(&c, b, &out); !s.ok()) Fail("GetRelationBatch", s);
      batched += n;
    }
    batch_s = std::chrono::duration<double>(Clock::now() - start).count();
  }

  // A job through the service, with its arrays.
  v1::RunJobRequest job;
  job.set_session_id(sid);
  v1::Algorithm algorithm = v1::ALGORITHM_UNSPECIFIED;
  std::string upper = "ALGORITHM_" + o.algorithm;
  for (char& ch : upper) ch = ch == '-' ? '_' : char(std::toupper(ch));
  v1::Algorithm_Parse(upper, &algorithm);
  job.set_algorithm(algorithm);
  job.set_include_arrays(true);
  double job_wall_s = 0, job_run_s = 0;
  {
    grpc::ClientContext c;
    const auto start = Clock::now();
    auto reader = stub->RunJob(&c, job);
    v1::RunJobResponse m;
    while (reader->Read(&m)) {
      if (m.has_stats()) job_run_s = m.stats().run_seconds();
    }
    if (auto s = reader->Finish(); !s.ok()) Fail("RunJob", s);
    job_wall_s = std::chrono::duration<double>(Clock::now() - start).count();
  }

  Json j;
  j["mesh"] = {{"sample", o.sample}, {"vertices", nv}, {"tetrahedra", mesh.mesh().tetrahedra()}};
  j["structure"] = o.structure;
  j["relation"] = o.relation;
  j["unary"] = {{"clients", o.clients},
                {"requests", all.size()},
                {"qps", unary_qps},
                {"p50_ms", Percentile(all, 0.50)},
                {"p90_ms", Percentile(all, 0.90)},
                {"p99_ms", Percentile(all, 0.99)}};
  j["stream"] = {{"relations", streamed}, {"seconds", stream_s},
                 {"relations_per_s", streamed / std::max(stream_s, 1e-9)}};
  j["batch"] = {{"batch_size", o.batch}, {"relations", batched}, {"seconds", batch_s},
                {"relations_per_s", batched / std::max(batch_s, 1e-9)}};
  j["job"] = {{"algorithm", o.algorithm}, {"wall_s", job_wall_s}, {"run_s", job_run_s},
              {"overhead_s", job_wall_s - job_run_s}};
  if (o.json) {
    std::cout << j.dump(1) << "\n";
  } else {
    std::printf("unary   %d client(s): %.0f req/s, p50 %.3f ms, p90 %.3f ms, p99 %.3f ms\n",
                o.clients, unary_qps, j["unary"]["p50_ms"].get<double>(),
                j["unary"]["p90_ms"].get<double>(), j["unary"]["p99_ms"].get<double>());
    std::printf("stream  %lld relations in %.2f s: %.0f relations/s\n", (long long)streamed,
                stream_s, streamed / std::max(stream_s, 1e-9));
    std::printf("batch   %lld relations in %.2f s: %.0f relations/s\n", (long long)batched,
                batch_s, batched / std::max(batch_s, 1e-9));
    std::printf("job     %s: %.3f s wall through the service, %.3f s running\n",
                o.algorithm.c_str(), job_wall_s, job_run_s);
  }
  v1::CloseSessionRequest close;
  close.set_session_id(sid);
  v1::CloseSessionResponse closed;
  grpc::ClientContext c;
  stub->CloseSession(&c, close, &closed);
  return 0;
}
