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
#include <string_view>
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
    // CPUs the daemon may run on (sched_setaffinity in the child before exec); empty = those
    // of the caller. A benchmark keeps the daemon and its simulated clients apart with it.
    // CPUs the machine does not offer make the child exit with code 126 before exec (start()
    // then reports "exited before listening (exit code 126)").
    std::vector<int> cpus;
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
  // Sends `sig` and waits up to `limit` for the exit (no escalation): the exit code, 128 +
  // signal when killed by one, -1 when it was not running or is still running at `limit`
  // (then it stays managed: stop() or the destructor end it).
  int signalAndWait(int sig, std::chrono::milliseconds limit);

 private:
  LocalDaemon() = default;
  pid_t pid_ = -1;
  int port_ = 0;
  std::filesystem::path dir_;  // port file, logs (and the cache when none was given)
};

// A CPU list in taskset/cpuset syntax ("0-1", "2-15", "0,2,4-7") -> CPU numbers, sorted,
// without duplicates. Errors name the bad part.
Expected<std::vector<int>> parseCpuList(std::string_view list);

// Restricts the calling thread, and the threads it creates afterwards, to `cpus`.
Status pinCurrentThread(const std::vector<int>& cpus);

}  // namespace lightlink::client
