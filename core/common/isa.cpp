#include "core/common/isa.h"

#include <atomic>
#include <cstdio>
#include <cstdlib>
#include <string>

#if defined(__x86_64__) || defined(__i386__)
#include <cpuid.h>
#endif

namespace lightlink {
namespace {

Isa detect() {
#if defined(__x86_64__) || defined(__i386__)
  __builtin_cpu_init();
  // libgcc's and compiler-rt's feature bits include the OS's YMM/ZMM state. F16C is read
  // from CPUID leaf 1 (ECX bit 29): clang 14's __builtin_cpu_supports does not know "f16c".
  unsigned eax = 0, ebx = 0, ecx = 0, edx = 0;
  const bool f16c = __get_cpuid(1, &eax, &ebx, &ecx, &edx) != 0 && (ecx & bit_F16C) != 0;
  if (!(__builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma") && f16c)) return Isa::kBaseline;
  if (__builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512bw") &&
      __builtin_cpu_supports("avx512cd") && __builtin_cpu_supports("avx512dq") && __builtin_cpu_supports("avx512vl"))
    return Isa::kAvx512;
  return Isa::kAvx2;
#else
  return Isa::kBaseline;
#endif
}

// -1: not read yet.
std::atomic<int> g_limit{-1};

int limit() {
  int l = g_limit.load(std::memory_order_relaxed);
  if (l >= 0) return l;
  l = int(Isa::kAvx512);
  if (const char* env = std::getenv("LIGHTLINK_ISA"); env && *env) {
    if (auto parsed = parseIsa(env)) {
      l = int(*parsed);
    } else {
      // The baseline runs on every CPU; say so rather than pick a tier silently.
      std::fprintf(stderr, "lightlink: LIGHTLINK_ISA: %s; running the baseline code\n",
                   parsed.status().message().c_str());
      l = int(Isa::kBaseline);
    }
  }
  int expected = -1;
  g_limit.compare_exchange_strong(expected, l, std::memory_order_relaxed);
  return g_limit.load(std::memory_order_relaxed);
}

}  // namespace

Isa cpuIsa() {
  static const Isa isa = detect();
  return isa;
}

Isa activeIsa() {
  const int cpu = int(cpuIsa()), cap = limit();
  return static_cast<Isa>(cpu < cap ? cpu : cap);
}

void setIsaLimit(Isa cap) { g_limit.store(int(cap), std::memory_order_relaxed); }

Expected<Isa> parseIsa(std::string_view name) {
  if (auto v = enumValue(kIsaNames, name)) return *v;
  return invalidInput("isa '{}' is not one of baseline, avx2, avx512", name);
}

bool isaClonesBuilt() {
#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__)
  return true;
#else
  return false;
#endif
}

}  // namespace lightlink
