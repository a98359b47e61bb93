// LocalDaemon: starts a lightlinkd process on loopback for a tool that wants its own daemon
// (an editor launching one beside itself, the service benchmark, the integration tests):
// `--listen 127.0.0.1:0 --port-file F --cache-dir D`, waiting (bounded) for the port the
// daemon picked. The destructor stops it with SIGTERM (the daemon drains its streams), and
// SIGKILL if it has not exited in time. POSIX only.
#pragma once

#include <sys/types.h>

#include <chrono>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "core/common/status.h"

namespace lightlink::client {

class LocalDaemon {
 public:
  struct Options {
    std::string binary;                 // path of lightlinkd (or of `lightlink`, with prefix {"serve"})
    std::vector<std::string> prefix;    // arguments before the flags below (e.g. {"serve"})
    std::filesystem::path cache_dir;    // artifacts; empty = a fresh temp dir removed at the end
    std::vector<std::string> extra;     // more daemon flags
    std::chrono::milliseconds start_timeout{30000};
  };

  static Expected<std::unique_ptr<LocalDaemon>> start(const Options& options);
  ~LocalDaemon();
  LocalDaemon(const LocalDaemon&) = delete;
  LocalDaemon& operator=(const LocalDaemon&) = delete;

  int port() const { return port_; }
  pid_t pid() const { return pid_; }
  std::string target() const { return "127.0.0.1:" + std::to_string(port_); }
  // The daemon's stderr and stdout so far (its structured log).
  std::string log() const;
  // SIGTERM, then waits up to `limit`; SIGKILL after that. Returns the exit code, 128 + signal
  // when killed, -1 when it was not running.
  int stop(std::chrono::milliseconds limit = std::chrono::milliseconds(10000));

 private:
  LocalDaemon() = default;
  pid_t pid_ = -1;
  int port_ = 0;
  std::filesystem::path dir_;  // port file, logs (and the cache when none was given)
};

}  // namespace lightlink::client
