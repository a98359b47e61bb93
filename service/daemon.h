// runDaemon: lightlinkd's whole life — parse flags, restore sessions, serve, drain on
// SIGTERM/SIGINT, exit. `lightlinkd`'s main and `lightlink serve` both call it.
//
// Exit codes: 0 after a clean drain (or --help/--version), 2 for bad flags or config, 1 when
// the daemon cannot start (cannot listen, cannot create the cache directory). SIGTERM and
// SIGINT are blocked in every thread and received by the calling thread with sigwait, so
// no handler runs in signal context.
#pragma once

namespace lightlink::service {

int runDaemon(int argc, char** argv);

}  // namespace lightlink::service
