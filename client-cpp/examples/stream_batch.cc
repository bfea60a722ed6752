// The same relation asked one simplex per call (latency), then over every vertex: streamed one
// simplex per message (one answer per request id, errors in band), batched (CSR arrays) and
// streamed in batches (CSR arrays per message, bad items reported by position), with their
// throughput.
//
//   stream_batch [HOST:PORT] [SAMPLE] [STRUCTURE] [CLIENTS]
//   (defaults: sample:jittered:24, actopo, 1 thread asking one per call; SAMPLE may be written
//   with or without its "sample:")
#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <iostream>
#include <numeric>
#include <span>
#include <string>
#include <thread>

#include "actopo/client.h"

namespace {

double SecondsSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

}  // namespace

int main(int argc, char** argv) {
  absl::StatusOr<std::unique_ptr<actopo::client::Client>> connected =
      actopo::client::Client::Connect(argc > 1 ? argv[1] : "");
  if (!connected.ok()) {
    std::cerr << connected.status() << "\n";
    return 1;
  }
  actopo::client::Client& client = **connected;
  std::string sample = argc > 2 ? argv[2] : "sample:jittered:24";
  if (!sample.starts_with("sample:")) sample = "sample:" + sample;
  absl::StatusOr<actopo::client::MeshInfo> mesh = client.LoadMesh(sample);
  if (!mesh.ok()) {
    std::cerr << mesh.status() << "\n";
    return 1;
  }
  const std::string structure = argc > 3 ? argv[3] : "actopo";
  actopo::client::SessionOptions options;
  options.structure = structure == "explicit"  ? actopo::client::Structure::kExplicit
                      : structure == "compact" ? actopo::client::Structure::kCompact
                                               : actopo::client::Structure::kActopo;
  absl::StatusOr<actopo::client::SessionInfo> session = client.OpenSession(mesh->mesh_id, options);
  if (!session.ok()) {
    std::cerr << session.status() << "\n";
    return 1;
  }

  // One per call: the round trip of a single query, 5000 vertices from each of CLIENTS threads
  // sharing the client (it is thread-safe).
  const int clients = argc > 4 ? std::max(1, std::atoi(argv[4])) : 1;
  std::vector<std::vector<double>> per_thread(clients);
  std::vector<std::thread> threads;
  for (int t = 0; t < clients; ++t) {
    threads.emplace_back([&, t] {
      for (int64_t i = 0; i < std::min<int64_t>(mesh->vertices, 5000); ++i) {
        const int64_t v = (i + 5000 * t) % mesh->vertices;
        const auto sent = std::chrono::steady_clock::now();
        if (!client.Relation(session->session_id, "vertex_star", v).ok()) return;
        per_thread[t].push_back(1e6 * SecondsSince(sent));
      }
    });
  }
  for (std::thread& t : threads) t.join();
  std::vector<double> latencies_us;
  for (const auto& l : per_thread) latencies_us.insert(latencies_us.end(), l.begin(), l.end());
  if (latencies_us.empty()) return 1;
  std::sort(latencies_us.begin(), latencies_us.end());
  const auto percentile = [&](double p) {
    return int64_t(
        latencies_us[std::min(latencies_us.size() - 1, size_t(p * latencies_us.size()))]);
  };
  std::cout << "one per call: " << clients << " thread(s), " << latencies_us.size()
            << " calls, p50 " << percentile(0.5) << " us, p99 " << percentile(0.99) << " us\n";

  // Every vertex, plus one id past the end to show an error in the stream.
  std::vector<int64_t> ids(size_t(mesh->vertices) + 1);
  std::iota(ids.begin(), ids.end(), 0);

  auto start = std::chrono::steady_clock::now();
  int64_t answered = 0, failed = 0, total = 0;
  const absl::Status streamed = client.StreamRelations(
      session->session_id, "vertex_star", ids, [&](actopo::client::StreamItem item) {
        if (item.ids.ok()) {
          ++answered;
          total += int64_t(item.ids->size());
        } else {
          ++failed;
          std::cout << "request " << item.request_id << ": " << item.ids.status() << "\n";
        }
      });
  const double stream_s = SecondsSince(start);
  std::cout << "stream: " << streamed << ", " << answered << " answers, " << failed << " errors, "
            << total << " tetrahedra, " << int64_t(double(answered) / stream_s) << " queries/s\n";

  ids.pop_back();  // a batch fails as a whole on a bad id
  start = std::chrono::steady_clock::now();
  absl::StatusOr<actopo::client::RelationCsr> batch =
      client.RelationBatch(session->session_id, "vertex_star", ids);
  const double batch_s = SecondsSince(start);
  if (batch.ok()) {
    std::cout << "batch: " << batch->size() << " rows, " << batch->values.size() << " tetrahedra, "
              << int64_t(double(batch->size()) / batch_s) << " queries/s\n";
  } else {
    std::cerr << "batch: " << batch.status() << "\n";
  }

  // Batches of 65536 on one stream, written ahead of the answers; the last one holds a bad id.
  ids.push_back(int64_t(ids.size()));
  constexpr size_t kChunk = 65536;
  absl::StatusOr<std::unique_ptr<actopo::client::RelationStream>> stream =
      client.OpenRelationStream();
  if (!stream.ok()) {
    std::cerr << stream.status() << "\n";
    return 1;
  }
  start = std::chrono::steady_clock::now();
  std::thread writer([&] {
    for (size_t first = 0; first < ids.size(); first += kChunk) {
      const size_t count = std::min(kChunk, ids.size() - first);
      const std::span<const int64_t> chunk(ids.data() + first, count);
      if (!(*stream)->WriteBatch(int64_t(first), session->session_id, "vertex_star", chunk).ok()) {
        break;
      }
    }
    (*stream)->WritesDone().IgnoreError();
  });
  int64_t rows = 0, batch_values = 0;
  while (std::optional<actopo::client::StreamItem> item = (*stream)->Read()) {
    rows += int64_t(item->rows.size());
    batch_values += int64_t(item->rows.values.size());
    for (const actopo::client::ItemError& e : item->item_errors) {
      std::cout << "item " << item->request_id + e.index << ": " << e.status << "\n";
    }
  }
  writer.join();
  const absl::Status batches = (*stream)->Finish();
  const double batches_s = SecondsSince(start);
  std::cout << "streamed batches: " << batches << ", " << rows << " rows, " << batch_values
            << " tetrahedra, " << int64_t(double(rows) / batches_s) << " queries/s\n";

  client.CloseSession(session->session_id).IgnoreError();
  client.DeleteMesh(mesh->mesh_id).IgnoreError();
  return streamed.ok() && batch.ok() && batches.ok() && total == int64_t(batch->values.size()) &&
                 batch_values == total
             ? 0
             : 1;
}
