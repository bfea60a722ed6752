// Prometheus metrics of the server, served on their own port (prometheus-cpp). Labels are
// low-cardinality only: RPC and status code, algorithm, structure; never ids.
#ifndef ACTOPO_SERVER_SERVICE_METRICS_H_
#define ACTOPO_SERVER_SERVICE_METRICS_H_

#include <functional>
#include <memory>
#include <string>
#include <string_view>

#include "absl/status/statusor.h"
#include "server/core/actopo_structure.h"

namespace prometheus {
class Exposer;
class Registry;
}  // namespace prometheus

namespace actopo::service {

// The gauges, read when Prometheus scrapes (never on the request path).
struct GaugeValues {
  int meshes = 0;
  int sessions = 0;
  int64_t budget_used_bytes = 0;
  int64_t budget_limit_bytes = 0;
  int64_t process_rss_bytes = 0;
  int64_t process_heap_bytes = 0;
  int engine_threads = 0;
  int uploads = 0;
  int64_t upload_bytes = 0;  // announced sizes of the uploads held (their budget's use)
};

class Metrics {
 public:
  // port 0: metrics are counted but not served.
  static absl::StatusOr<std::unique_ptr<Metrics>> Create(const std::string& host, int port);
  ~Metrics();

  void Request(std::string_view rpc, int grpc_code);
  void Job(std::string_view algorithm, std::string_view structure, double seconds,
           const EngineStats& engine);
  // Called on the exposer's thread at each scrape; nullptr stops it (before what it reads goes).
  void SetGaugeSource(std::function<GaugeValues()> source);
  int port() const { return port_; }

 private:
  Metrics() = default;
  struct Families;
  class ScrapeTimeGauges;
  std::shared_ptr<ScrapeTimeGauges> collectable_;
  std::shared_ptr<prometheus::Registry> registry_;
  std::unique_ptr<prometheus::Exposer> exposer_;
  std::unique_ptr<Families> f_;
  int port_ = 0;
};

}  // namespace actopo::service

#endif  // ACTOPO_SERVER_SERVICE_METRICS_H_
