// Exit codes of the `lightlink` CLI, documented in docs/cli.md. CI jobs branch on these,
// so they distinguish the user's fault (fix the input) from ours (file a bug).
#pragma once

#include <new>

#include "core/common/status.h"

namespace lightlink::cli {

enum ExitCode : int {
  kExitOk = 0,
  kExitUsage = 1,        // bad command line (CLI11 also uses 1... see docs/cli.md)
  kExitBadInput = 2,     // invalid or unsupported scene / parameters, missing file
  kExitIoError = 3,      // could not read or write a file for OS reasons
  kExitInternal = 4,     // a bug in lightlink
  kExitResources = 5,    // over a limit (docs/cli.md "Limits") or out of memory
  // `bake --fail-on`: every output was written, but the bake has warnings (--fail-on
  // warning) or is dark: no light at all, or an all-black lightmap (--fail-on dark|warning).
  kExitWarnings = 6,
  kExitDark = 7,
};

int exitCodeFor(const Status& status);

// Prints "lightlink <command>: <message>" to stderr and returns the exit code.
int reportError(const char* command, const Status& status);

// Runs a command, turning std::bad_alloc (anywhere, in any thread TBB joins) into a message
// and kExitResources instead of an abort with no message.
template <typename F>
int runGuarded(const char* command, F&& f) {
  try {
    return f();
  } catch (const std::bad_alloc&) {
    return reportError(command, resourceExhausted("out of memory (lower --resolution, --surfels or --links, or "
                                                  "raise the texel size)"));
  }
}

}  // namespace lightlink::cli
