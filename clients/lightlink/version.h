// The lightlink version and the source it was built from, for `lightlink --version` and
// bake's report.json. The commit is `git describe --always --dirty` taken when CMake
// configured the build ("unknown" outside a git checkout); reconfigure to refresh it.
#pragma once

namespace lightlink::cli {

const char* lightlinkVersion();  // "0.1.0", the CMake project version
const char* lightlinkCommit();   // e.g. "b984901" or "b984901-dirty"; "unknown" when not known

}  // namespace lightlink::cli
