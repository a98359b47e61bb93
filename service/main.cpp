// lightlinkd: the lightlink daemon (docs/service.md). Everything is in runDaemon.
#include <cstdio>
#include <cstdlib>

#include "service/daemon.h"

int main(int argc, char** argv) {
  const int rc = lightlink::service::runDaemon(argc, argv);
  // Everything durable is written by now (sessions saved, journal synced, logs flushed).
  // Exit without static destructors: gRPC's global shutdown at exit sometimes waits ~10 s on
  // an internal timer, which a supervisor sending SIGTERM would take for a hung daemon.
  std::fflush(nullptr);
  std::_Exit(rc);
}
