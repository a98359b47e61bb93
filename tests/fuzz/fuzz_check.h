// What a fuzzer does when an input breaks a contract that is not a crash (an accepted input
// that its consumer then fails on, a round trip that loses data): print why and abort, so
// libFuzzer saves the input like any crash.
#pragma once

#include <cstdio>
#include <cstdlib>

#include "core/common/status.h"

namespace lightlink::fuzz {

inline void require(bool ok, const char* what, const Status& why) {
  if (ok) return;
  std::fprintf(stderr, "fuzz contract broken: %s: %s\n", what, why.toString().c_str());
  std::abort();
}

}  // namespace lightlink::fuzz
