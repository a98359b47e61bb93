// runDaemon: lightlinkd's whole life — parse flags, restore sessions, serve, drain on
// SIGTERM/SIGINT, exit. `lightlinkd`'s main and `lightlink serve` both call it.
//
// Exit codes: 0 after a clean drain (or --help/--version), 2 for bad flags or config, 1 when
// the daemon cannot start (cannot listen, cannot create the cache directory). SIGTERM and
// SIGINT are blocked in every thread and received by the calling thread with sigwait, so
// no handler runs in signal context.
//
// Hooks let the process that embeds the daemon (`lightlink serve` and its web gateway) start
// its own work once the daemon listens and stop it when the drain begins, without the
// service knowing what that work is.
#pragma once

#include <functional>

#include "core/common/status.h"
#include "service/config.h"

namespace lightlink::service {

struct DaemonHooks {
  // After the server listens (`port` is the bound one); a failure stops the daemon, exit 1.
  std::function<Status(const DaemonConfig& config, int port)> on_listening;
  // On SIGTERM/SIGINT, before open streams are drained.
  std::function<void()> on_draining;
};

int runDaemon(int argc, char** argv, const DaemonHooks& hooks = {});

}  // namespace lightlink::service
