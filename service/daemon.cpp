#include "service/daemon.h"

#include <pthread.h>
#include <signal.h>

#include <cerrno>
#include <chrono>
#include <cstdlib>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <thread>

#include <grpc/grpc.h>
#include <grpcpp/grpcpp.h>
#include <grpcpp/health_check_service_interface.h>

#include "core/common/private_files.h"
#include "service/config.h"
#include "service/logging.h"
#include "service/scene_registry.h"
#include "service/service.h"
#include "service/shared_results.h"
#include "service/session_store.h"

namespace lightlink::service {
namespace {

namespace fs = std::filesystem;

Expected<std::string> readFile(const std::string& path, const char* flag) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return notFound("{} {}: cannot read", flag, path);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

Expected<std::shared_ptr<grpc::ServerCredentials>> credentialsFor(const DaemonConfig& c) {
  if (c.tls_cert.empty()) return grpc::InsecureServerCredentials();
  auto cert = readFile(c.tls_cert, "--tls-cert");
  if (!cert) return cert.status();
  auto key = readFile(c.tls_key, "--tls-key");
  if (!key) return key.status();
  grpc::SslServerCredentialsOptions o;
  o.pem_key_cert_pairs.push_back({*key, *cert});
  return grpc::SslServerCredentials(o);
}

// A daemon (or a bake) killed while writing leaves ".<name>.tmp.<pid>.<n>" files behind
// (artifact.cpp, session_store.cpp). Those of processes that no longer exist are garbage;
// those of live processes (a bake sharing the cache) are left alone.
void removeStaleTempFiles(const fs::path& cache_dir) {
  std::error_code ec;
  for (const auto& e : fs::directory_iterator(cache_dir, ec)) {
    const std::string name = e.path().filename().string();
    const auto at = name.find(".tmp.");
    if (name.empty() || name[0] != '.' || at == std::string::npos) continue;
    const pid_t pid = static_cast<pid_t>(std::atol(name.c_str() + at + 5));
    if (pid <= 0 || (::kill(pid, 0) != 0 && errno == ESRCH)) {
      std::error_code rm;
      if (fs::remove(e.path(), rm))
        logEvent(LogLevel::kInfo, "stale_temp_removed", {{"path", e.path().string()}});
    }
  }
}

int fail(const std::string& event, const std::string& message) {
  logEvent(LogLevel::kError, event, {{"error", message}});
  flushLogs();
  std::fprintf(stderr, "lightlinkd: %s\n", message.c_str());
  return 1;
}

}  // namespace

int runDaemon(int argc, char** argv, const DaemonHooks& hooks) {
  // Before any thread exists (gRPC, TBB, scene workers): every thread inherits the mask,
  // so SIGTERM/SIGINT reach only the sigwait below. SIGPIPE is ignored: a client closing
  // its socket must not kill the daemon.
  sigset_t signals;
  sigemptyset(&signals);
  sigaddset(&signals, SIGTERM);
  sigaddset(&signals, SIGINT);
  pthread_sigmask(SIG_BLOCK, &signals, nullptr);
  ::signal(SIGPIPE, SIG_IGN);

  ParsedArgs args = parseArgs(argc, argv);
  if (args.exit_now) {
    std::fputs(args.output.c_str(), args.exit_code == 0 ? stdout : stderr);
    return args.exit_code;
  }
  const DaemonConfig& config = args.config;
  if (Status s = initLogging(config); !s) {
    std::fprintf(stderr, "lightlinkd: %s\n", s.message().c_str());
    return 2;
  }
  if (Status s = createPrivateDirectories(config.cache_dir); !s)
    return fail("start_failed", "--cache-dir " + config.cache_dir + ": " + s.message());
  removeStaleTempFiles(config.cache_dir);
  removeStaleTempFiles(fs::path(config.cache_dir) / "inline");  // uploads staged while their scene opened
  auto creds = credentialsFor(config);
  if (!creds) return fail("start_failed", creds.status().message());

  // Shared-memory results of a daemon that was killed (its pid gone) are left under the base.
  if (const int stale = removeStaleSharedDirs(config.shared_memory_dir); stale > 0)
    logEvent(LogLevel::kInfo, "shared_memory_cleaned", {{"dir", config.shared_memory_dir}, {"removed", stale}});
  SceneRegistry registry(config);
  // Returns at once: the scenes are re-opened in the background while the server answers.
  if (config.restore_sessions) registry.restore();
  LightlinkService service(config, registry);

  // gRPC's standard health service cannot check the bearer token: with a token it is off
  // and lightlink.v1 Health (behind the token) is the probe.
  // One gRPC reference held for the process's life (lightlinkd ends in _Exit): without it
  // ~Server drops the last one, and grpc_shutdown joins an executor thread that may sit in
  // epoll_wait for up to ~10 s, which a supervisor's SIGTERM would see as a hung daemon.
  grpc_init();
  grpc::EnableDefaultHealthCheckService(config.token.empty());
  grpc::ServerBuilder builder;
  int port = 0;
  builder.AddListeningPort(config.listen, *creds, &port);
  // Threads the synchronous server keeps polling for calls between them. With gRPC's default
  // (2), a thread whose call ends while two others poll exits and a new one is started for
  // the next call: with 50 long-polling clients the daemon spends its cores creating and
  // destroying threads (clone3 and munmap calls in a run of service_bench), and the
  // 50-client latency rises. An idle poller costs a thread stack.
  builder.SetSyncServerOption(grpc::ServerBuilder::SyncServerOption::MAX_POLLERS, 128);
  builder.SetMaxReceiveMessageSize(static_cast<int>(config.max_receive_bytes));
  builder.SetMaxSendMessageSize(static_cast<int>(config.max_send_bytes));
  builder.RegisterService(&service);
  std::unique_ptr<grpc::Server> server = builder.BuildAndStart();
  if (!server || port == 0) return fail("start_failed", "--listen " + config.listen + ": cannot listen there");
  if (!config.port_file.empty()) {
    if (Status s = writeFileAtomic(config.port_file, std::to_string(port) + "\n", 0644); !s) {
      server->Shutdown();
      return fail("start_failed", "--port-file: " + s.message());
    }
  }
  logEvent(LogLevel::kInfo, "listening",
           {{"listen", config.listen},
            {"port", port},
            {"tls", !config.tls_cert.empty()},
            {"auth", config.token.empty() ? "none (loopback)" : "bearer"},
            {"cache_dir", config.cache_dir},
            {"shared_memory", config.shared_memory_dir.empty() ? "off" : config.shared_memory_dir},
            {"scenes", registry.size()}});

  if (hooks.on_listening) {
    if (Status s = hooks.on_listening(config, port); !s) {
      server->Shutdown(std::chrono::system_clock::now());
      server->Wait();
      (void)registry.shutdown();
      return fail("start_failed", s.message());
    }
  }

  int sig = 0;
  while (sigwait(&signals, &sig) != 0) {
  }
  if (hooks.on_draining) hooks.on_draining();
  logEvent(LogLevel::kInfo, "draining", {{"signal", sig == SIGTERM ? "SIGTERM" : "SIGINT"},
                                         {"streams", service.activeStreams()}});
  service.beginDrain();
  if (auto* health = server->GetHealthCheckService()) health->SetServingStatus(false);
  // Open streams end at their next message boundary; give them the drain time, then stop
  // the server (which cancels whatever is still running after a short grace).
  const auto drain_until = std::chrono::steady_clock::now() +
                           std::chrono::milliseconds(static_cast<long long>(config.drain_seconds * 1000.0));
  while (service.activeStreams() > 0 && std::chrono::steady_clock::now() < drain_until)
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  const int left = service.activeStreams();
  // Unary calls in flight get a short grace; gRPC's sync server otherwise waits out the
  // whole deadline while idle client connections are open.
  server->Shutdown(std::chrono::system_clock::now() + std::chrono::milliseconds(left > 0 ? 1000 : 200));
  server->Wait();
  logEvent(LogLevel::kDebug, "server_stopped", {});
  Status persisted = registry.shutdown();
  logEvent(LogLevel::kInfo, "stopped", {{"streams_cut", left}, {"sessions_saved", persisted.isOk()}});
  flushLogs();
  return 0;
}

}  // namespace lightlink::service
