#include "core/common/process_memory.h"

#include <cstdio>
#include <cstring>

namespace lightlink {
namespace {

std::uint64_t statusKiB(const char* field) {
  std::FILE* f = std::fopen("/proc/self/status", "r");
  if (f == nullptr) return 0;
  char line[256];
  std::uint64_t kib = 0;
  const std::size_t n = std::strlen(field);
  while (std::fgets(line, sizeof(line), f) != nullptr) {
    if (std::strncmp(line, field, n) == 0 && line[n] == ':') {
      unsigned long long v = 0;
      if (std::sscanf(line + n + 1, "%llu", &v) == 1) kib = v;
      break;
    }
  }
  std::fclose(f);
  return kib * 1024;
}

}  // namespace

std::uint64_t residentBytes() { return statusKiB("VmRSS"); }
std::uint64_t peakResidentBytes() { return statusKiB("VmHWM"); }

}  // namespace lightlink
