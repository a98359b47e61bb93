// Resident memory of this process, for the reports that say what a stage cost (bake's
// "load" section). Linux: read from /proc/self/status; 0 where it cannot be read.
#pragma once

#include <cstdint>

namespace lightlink {

std::uint64_t residentBytes();      // VmRSS: resident now
std::uint64_t peakResidentBytes();  // VmHWM: the most resident at once since the process started

}  // namespace lightlink
