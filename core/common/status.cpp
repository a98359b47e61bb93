#include "core/common/status.h"

namespace lightlink {

const char* codeName(Code code) {
  switch (code) {
    case Code::kOk: return "ok";
    case Code::kInvalidInput: return "invalid input";
    case Code::kUnsupported: return "unsupported";
    case Code::kNotFound: return "not found";
    case Code::kIoError: return "i/o error";
    case Code::kInternal: return "internal error";
    case Code::kResourceExhausted: return "resource exhausted";
    case Code::kCancelled: return "cancelled";
  }
  return "unknown";
}

std::string Status::toString() const {
  if (isOk()) return "ok";
  return fmt::format("{}: {}", codeName(code_), message_);
}

}  // namespace lightlink
