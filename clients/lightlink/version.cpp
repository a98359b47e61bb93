#include "clients/lightlink/version.h"

// Generated at configure time (clients/CMakeLists.txt); only this file includes it, so a
// new commit recompiles one file.
#include "lightlink_build_info.h"

namespace lightlink::cli {

const char* lightlinkVersion() { return LIGHTLINK_BUILD_VERSION; }
const char* lightlinkCommit() { return LIGHTLINK_BUILD_COMMIT; }

}  // namespace lightlink::cli
