#include "clients/lightlink/exit_codes.h"

#include <cstdio>

namespace lightlink::cli {

int exitCodeFor(const Status& status) {
  switch (status.code()) {
    case Code::kOk: return kExitOk;
    case Code::kInvalidInput:
    case Code::kUnsupported:
    case Code::kNotFound: return kExitBadInput;
    case Code::kIoError: return kExitIoError;
    case Code::kInternal: return kExitInternal;
    case Code::kResourceExhausted: return kExitResources;
    case Code::kCancelled: return kExitInternal;  // the CLI never cancels its own work
  }
  return kExitInternal;
}

int reportError(const char* command, const Status& status) {
  std::fprintf(stderr, "lightlink %s: %s\n", command, status.toString().c_str());
  return exitCodeFor(status);
}

}  // namespace lightlink::cli
