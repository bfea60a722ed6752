// The same relation over every vertex, streamed (one answer per request id, errors in band) and
// batched (CSR arrays), with their throughput.
//
//   stream_batch [HOST:PORT] [SAMPLE]      (default SAMPLE: jittered:24)
#include <chrono>
#include <iostream>
#include <numeric>
#include <string>

#include "actopo/client.h"

namespace {

double SecondsSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

}  // namespace

int main(int argc, char** argv) {
  absl::StatusOr<std::unique_ptr<actopo::Client>> connected =
      actopo::Client::Connect(argc > 1 ? argv[1] : "");
  if (!connected.ok()) {
    std::cerr << connected.status() << "\n";
    return 1;
  }
  actopo::Client& client = **connected;
  const std::string sample = argc > 2 ? argv[2] : "jittered:24";
  absl::StatusOr<actopo::MeshInfo> mesh = client.LoadMesh("sample:" + sample);
  if (!mesh.ok()) {
    std::cerr << mesh.status() << "\n";
    return 1;
  }
  absl::StatusOr<actopo::SessionInfo> session = client.OpenSession(mesh->mesh_id);
  if (!session.ok()) {
    std::cerr << session.status() << "\n";
    return 1;
  }

  // Every vertex, plus one id past the end to show an error in the stream.
  std::vector<int64_t> ids(size_t(mesh->vertices) + 1);
  std::iota(ids.begin(), ids.end(), 0);

  auto start = std::chrono::steady_clock::now();
  int64_t answered = 0, failed = 0, total = 0;
  const absl::Status streamed = client.StreamRelations(
      session->session_id, "vertex_star", ids, [&](actopo::StreamItem item) {
        if (item.ids.ok()) {
          ++answered;
          total += int64_t(item.ids->size());
        } else {
          ++failed;
          std::cout << "request " << item.request_id << ": " << item.ids.status() << "\n";
        }
      });
  const double stream_s = SecondsSince(start);
  std::cout << "stream: " << streamed << ", " << answered << " answers, " << failed
            << " errors, " << total << " tetrahedra, " << int64_t(double(answered) / stream_s)
            << " queries/s\n";

  ids.pop_back();  // a batch fails as a whole on a bad id
  start = std::chrono::steady_clock::now();
  absl::StatusOr<actopo::RelationCsr> batch =
      client.RelationBatch(session->session_id, "vertex_star", ids);
  const double batch_s = SecondsSince(start);
  if (batch.ok()) {
    std::cout << "batch: " << batch->size() << " rows, " << batch->values.size()
              << " tetrahedra, " << int64_t(double(batch->size()) / batch_s) << " queries/s\n";
  } else {
    std::cerr << "batch: " << batch.status() << "\n";
  }

  client.CloseSession(session->session_id).IgnoreError();
  client.DeleteMesh(mesh->mesh_id).IgnoreError();
  return streamed.ok() && batch.ok() && total == int64_t(batch->values.size()) ? 0 : 1;
}
