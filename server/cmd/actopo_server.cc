// actopo-server: serves actopo.v1.TopologyService (plus grpc.health.v1 and reflection).
//
//   actopo-server --port 50051 --data-dir ../shared/data --metrics-port 9464
//
// SIGTERM or SIGINT drains: health turns NOT_SERVING, new calls get UNAVAILABLE, running jobs
// and loads are cancelled; after a moment (a quarter of --grace-s, at most 1 s) the server stops
// taking calls, waits up to --grace-s for calls to end and exits.
#include <signal.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iostream>
#include <string_view>
#include <thread>

#include "absl/strings/str_cat.h"
#include "server/cmd/flags.h"
#include "server/core/parallel.h"
#include "server/core/process_memory.h"
#include "server/service/server.h"

namespace {

// --test-gate-dir: the clients' tests hold a call's work at its start, as the server's own tests
// do with ServerOptions::before_work, from their own process. While the file DIR/NAME exists
// (NAME: the work's name with '/' as '.', e.g. RunJob, LoadMeshWithProgress.partition), work of
// that name waits before it begins, and DIR/NAME.held says that some does.
std::function<void(std::string_view)> FileGate(const std::filesystem::path& dir) {
  return [dir](std::string_view work) {
    std::string name(work);
    std::replace(name.begin(), name.end(), '/', '.');
    const std::filesystem::path hold = dir / name;
    std::error_code ec;
    if (!std::filesystem::exists(hold, ec)) return;
    const std::filesystem::path held = dir / (name + ".held");
    std::ofstream(held).close();
    while (std::filesystem::exists(hold, ec)) {
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
    }
    std::filesystem::remove(held, ec);
  };
}

}  // namespace

int main(int argc, char** argv) {
  actopo::ConfigureAllocator(actopo::DefaultThreads());
  actopo::service::ServerOptions o;
  // A default session runs a consumer and a producer per core: leave room for several.
  o.max_engine_threads = std::max(o.max_engine_threads, 4 * actopo::DefaultThreads());
  int memory_budget_mib = 0, max_message_mib = 64, idle_timeout_s = 1800, grace_s = 10;
  int upload_budget_mib = 8192, upload_timeout_s = 900;
  // Mesh files are read by actopo-read-mesh, installed beside this executable.
  std::error_code ec;
  std::string mesh_reader =
      (std::filesystem::read_symlink("/proc/self/exe", ec).parent_path() / "actopo-read-mesh")
          .string();
  std::string test_gate_dir;
  if (const char* token = std::getenv("ACTOPO_TOKEN")) o.token = token;
  actopo::FlagParser flags("actopo-server",
                           "serves the ACTOPO topology API (actopo.v1.TopologyService)");
  flags.Add("host", &o.host, "address to listen on");
  flags.Add("port", &o.port, "gRPC port (0: pick a free one; the chosen port is printed)");
  flags.Add("data-dir", &o.data_dir, "directory LoadMesh paths are relative to");
  flags.Add("mesh-reader", &mesh_reader,
            "actopo-read-mesh, which reads mesh files in a child process limited to the load's "
            "memory budget ('in-process': read in the server, where a file VTK crashes on ends "
            "the server)");
  flags.Add("metrics-port", &o.metrics_port, "Prometheus metrics port (0: off)");
  flags.Add("max-meshes", &o.max_meshes, "meshes held at once");
  flags.Add("max-sessions", &o.max_sessions, "sessions open at once");
  flags.Add("max-engine-threads", &o.max_engine_threads,
            "engine threads (producers and job consumers) over all sessions");
  flags.Add("memory-budget-mib", &memory_budget_mib,
            "memory budget for meshes and sessions in MiB (0: 75% of physical memory)");
  flags.Add("max-message-mib", &max_message_mib, "largest gRPC message in MiB");
  flags.Add("max-batch-size", &o.max_batch_size, "most simplices in one GetRelationBatch");
  flags.Add("session-idle-timeout-s", &idle_timeout_s, "close sessions idle this long");
  flags.Add("grace-s", &grace_s, "on SIGTERM, seconds to let calls finish");
  flags.Add("upload-dir", &o.upload_dir,
            "folder of the files being uploaded, one server's at a time (default: one in the "
            "system's temporary directory, removed at exit; a killed server's at the next "
            "start)");
  flags.Add("upload-budget-mib", &upload_budget_mib,
            "sizes of the uploads held at once in MiB (on disk, in --upload-dir)");
  flags.Add("upload-timeout-s", &upload_timeout_s,
            "drop an upload nobody has written to for this long");
  flags.Add("max-uploads", &o.max_uploads, "uploads held at once");
  flags.Add("tls-cert", &o.tls_cert_file, "PEM certificate chain (with --tls-key: serve TLS)");
  flags.Add("tls-key", &o.tls_key_file, "PEM private key");
  flags.Add("token", &o.token,
            "require 'authorization: Bearer TOKEN' on every call (default: $ACTOPO_TOKEN)");
  flags.Add("test-gate-dir", &test_gate_dir,
            "tests only: work of a call waits at its start while a file of its name is there");
  if (absl::Status s = flags.Parse(argc, argv); !s.ok()) {
    std::cerr << "actopo-server: " << s.message() << "\n";
    return 2;
  }
  if (flags.help_requested()) {
    std::cout << flags.Usage();
    return 0;
  }
  if (o.port < 0 || o.port > 65535) {
    std::cerr << "actopo-server: --port: " << o.port << " is outside [0, 65535]\n";
    return 2;
  }
  if (mesh_reader != "in-process") {
    if (!o.data_dir.empty() && ::access(mesh_reader.c_str(), X_OK) != 0) {
      std::cerr << "actopo-server: --mesh-reader: no executable at '" << mesh_reader
                << "'; install actopo-read-mesh beside actopo-server, give its path, or pass "
                   "--mesh-reader in-process\n";
      return 2;
    }
    o.mesh_reader = mesh_reader;
  }
  if (!test_gate_dir.empty()) o.before_work = FileGate(test_gate_dir);
  o.memory_budget_bytes = int64_t(memory_budget_mib) << 20;
  o.max_message_bytes = int64_t(max_message_mib) << 20;
  o.session_idle_timeout = absl::Seconds(idle_timeout_s);
  o.upload_budget_bytes = int64_t(upload_budget_mib) << 20;
  o.upload_timeout = absl::Seconds(upload_timeout_s);

  // Block the signals in every thread (gRPC's inherit the mask) and wait for them here.
  sigset_t signals;
  sigemptyset(&signals);
  sigaddset(&signals, SIGTERM);
  sigaddset(&signals, SIGINT);
  pthread_sigmask(SIG_BLOCK, &signals, nullptr);

  auto server = actopo::service::Server::Start(o);
  if (!server.ok()) {
    std::cerr << "actopo-server: " << server.status().message() << "\n";
    return 1;
  }
  std::printf("actopo-server listening on %s:%d\n", o.host.c_str(), (*server)->port());
  if ((*server)->metrics_port() > 0) {
    std::printf("actopo-server metrics on %s:%d/metrics\n", o.host.c_str(),
                (*server)->metrics_port());
  }
  std::fflush(stdout);
  int received = 0;
  sigwait(&signals, &received);
  std::fprintf(stderr, "actopo-server: %s received, draining\n",
               received == SIGTERM ? "SIGTERM" : "SIGINT");
  // Draining first, for a moment, before gRPC stops taking calls: meanwhile new calls get
  // UNAVAILABLE (which clients retry elsewhere) and health checks see NOT_SERVING. Stopping at
  // once, gRPC would cancel the calls arriving in the same instant instead.
  (*server)->Drain();
  std::this_thread::sleep_for(std::chrono::milliseconds(std::min(grace_s * 1000 / 4, 1000)));
  (*server)->Shutdown(absl::Seconds(grace_s));
  std::fprintf(stderr, "actopo-server: stopped\n");
  return 0;
}
