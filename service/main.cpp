// lightlinkd: the lightlink daemon (docs/service.md). Everything is in runDaemon.
#include "service/daemon.h"

int main(int argc, char** argv) { return lightlink::service::runDaemon(argc, argv); }
