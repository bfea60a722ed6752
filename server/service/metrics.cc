#include "server/service/metrics.h"

#include <prometheus/counter.h>
#include <prometheus/exposer.h>
#include <prometheus/gauge.h>
#include <prometheus/histogram.h>
#include <prometheus/registry.h>

#include "absl/strings/str_cat.h"
#include "server/core/sync.h"

namespace actopo::service {

struct Metrics::Families {
  prometheus::Family<prometheus::Counter>* requests;
  prometheus::Family<prometheus::Histogram>* job_seconds;
  prometheus::Counter* buffer_hits;
  prometheus::Counter* buffer_misses;
  prometheus::Counter* wait_seconds;
  prometheus::Gauge* meshes;
  prometheus::Gauge* sessions;
  prometheus::Gauge* budget_used;
  prometheus::Gauge* budget_limit;
  prometheus::Gauge* rss;
  prometheus::Gauge* heap;
  prometheus::Gauge* threads;
  prometheus::Gauge* uploads;
  prometheus::Gauge* upload_bytes;
};

// The registry as the exposer sees it: the gauges are set from the source, then collected.
class Metrics::ScrapeTimeGauges : public prometheus::Collectable {
 public:
  ScrapeTimeGauges(std::shared_ptr<prometheus::Registry> registry, const Families* families)
      : registry_(std::move(registry)), f_(families) {}

  void SetSource(std::function<GaugeValues()> source) {
    MutexLock lock(mu_);
    source_ = std::move(source);
  }

  std::vector<prometheus::MetricFamily> Collect() const override {
    {
      MutexLock lock(mu_);
      if (source_) {
        const GaugeValues v = source_();
        f_->meshes->Set(v.meshes);
        f_->sessions->Set(v.sessions);
        f_->budget_used->Set(double(v.budget_used_bytes));
        f_->budget_limit->Set(double(v.budget_limit_bytes));
        f_->rss->Set(double(v.process_rss_bytes));
        f_->heap->Set(double(v.process_heap_bytes));
        f_->threads->Set(v.engine_threads);
        f_->uploads->Set(v.uploads);
        f_->upload_bytes->Set(double(v.upload_bytes));
      }
    }
    return registry_->Collect();
  }

 private:
  const std::shared_ptr<prometheus::Registry> registry_;
  const Families* f_;
  mutable Mutex mu_;
  std::function<GaugeValues()> source_ ABSL_GUARDED_BY(mu_);
};

absl::StatusOr<std::unique_ptr<Metrics>> Metrics::Create(const std::string& host, int port) {
  auto m = std::unique_ptr<Metrics>(new Metrics());
  m->registry_ = std::make_shared<prometheus::Registry>();
  auto& r = *m->registry_;
  m->f_ = std::make_unique<Families>();
  m->f_->requests = &prometheus::BuildCounter()
                         .Name("actopo_requests_total")
                         .Help("RPCs answered, by method and gRPC status code")
                         .Register(r);
  m->f_->job_seconds = &prometheus::BuildHistogram()
                            .Name("actopo_job_duration_seconds")
                            .Help("Algorithm job durations, by algorithm and structure")
                            .Register(r);
  m->f_->buffer_hits = &prometheus::BuildCounter()
                            .Name("actopo_buffer_hits_total")
                            .Help("Block relation requests found ready, over all jobs")
                            .Register(r)
                            .Add({});
  m->f_->buffer_misses = &prometheus::BuildCounter()
                              .Name("actopo_buffer_misses_total")
                              .Help("Block relation requests that waited, over all jobs")
                              .Register(r)
                              .Add({});
  m->f_->wait_seconds = &prometheus::BuildCounter()
                             .Name("actopo_consumer_wait_seconds_total")
                             .Help("Time consumers waited for relations, over all jobs")
                             .Register(r)
                             .Add({});
  auto gauge = [&](const char* name, const char* help) {
    return &prometheus::BuildGauge().Name(name).Help(help).Register(r).Add({});
  };
  m->f_->meshes = gauge("actopo_meshes", "Loaded meshes");
  m->f_->sessions = gauge("actopo_sessions", "Open sessions");
  m->f_->budget_used = gauge("actopo_memory_budget_used_bytes",
                             "Bytes reserved by meshes and sessions in the memory budget");
  m->f_->budget_limit =
      gauge("actopo_memory_budget_limit_bytes", "The memory budget (--memory-budget-mib)");
  m->f_->rss = gauge("actopo_process_resident_bytes", "Resident memory of the server");
  m->f_->heap = gauge("actopo_process_heap_bytes",
                      "Bytes allocated and not freed in the server (free memory the allocator "
                      "keeps excluded)");
  m->f_->threads = gauge("actopo_engine_threads", "Engine threads reserved");
  m->f_->uploads = gauge("actopo_uploads", "Uploads held (CreateUpload), complete or not");
  m->f_->upload_bytes =
      gauge("actopo_upload_bytes", "Announced sizes of the uploads held (--upload-budget-mib)");
  m->collectable_ = std::make_shared<ScrapeTimeGauges>(m->registry_, m->f_.get());
  if (port > 0) {
    try {
      m->exposer_ = std::make_unique<prometheus::Exposer>(absl::StrCat(host, ":", port));
    } catch (const std::exception& e) {
      return absl::UnavailableError(
          absl::StrCat("metrics port ", port, ": cannot listen (", e.what(), ")"));
    }
    m->exposer_->RegisterCollectable(m->collectable_);
    m->port_ = int(m->exposer_->GetListeningPorts().front());
  }
  return m;
}

Metrics::~Metrics() = default;

void Metrics::Request(std::string_view rpc, int grpc_code) {
  f_->requests->Add({{"rpc", std::string(rpc)}, {"code", std::to_string(grpc_code)}}).Increment();
}

void Metrics::Job(std::string_view algorithm, std::string_view structure, double seconds,
                  const EngineStats& engine) {
  static const prometheus::Histogram::BucketBoundaries kBuckets = {0.01, 0.1, 0.5, 1,  2,
                                                                   5,    10,  30,  60, 300};
  f_->job_seconds
      ->Add({{"algorithm", std::string(algorithm)}, {"structure", std::string(structure)}},
            kBuckets)
      .Observe(seconds);
  f_->buffer_hits->Increment(double(engine.access.hits));
  f_->buffer_misses->Increment(double(engine.access.misses));
  f_->wait_seconds->Increment(engine.access.wait_ns * 1e-9);
}

void Metrics::SetGaugeSource(std::function<GaugeValues()> source) {
  collectable_->SetSource(std::move(source));
}

}  // namespace actopo::service
