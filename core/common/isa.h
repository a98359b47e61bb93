// Isa: the one place that decides which SIMD code runs (Embree's isa.h plays this part
// there). Every hot loop with vector variants asks activeIsa(): the relight's AVX2 + F16C
// link kernels, the AVX-512 cut and hit credit, the F16C half conversion, and the functions
// compiled once per tier with LL_ISA_CLONES. The tier is the best this CPU and OS run
// (cpuIsa), lowered by a limit: LIGHTLINK_ISA=baseline|avx2|avx512 in the environment (read
// once, at the first question), `--isa` on the CLI, or setIsaLimit() in tests and
// benchmarks. Every tier gives the same artifact bits, and the same relight results but for
// the relight's scalar link kernel (baseline), which sums in another order and agrees to
// float rounding; Isa.EveryTierGivesTheSameArtifact (tests/stability) forces each tier this
// machine has and compares.
//
//   baseline  x86-64 (SSE2) or any other CPU
//   avx2      AVX2 + FMA + F16C, with the OS saving YMM state
//   avx512    avx2 and AVX-512 F, BW, CD, DQ, VL (x86-64-v4), with the OS saving ZMM state
//
// Rule for LL_ISA_CLONES bodies: only operations that round the same in every lane width
// (adds, multiplies, divides, selects, moves), never a reassociated reduction; contraction
// into FMA is off in every clone.
#pragma once

#include <string_view>

#include "core/common/enum_names.h"
#include "core/common/status.h"

namespace lightlink {

enum class Isa : int { kBaseline = 0, kAvx2 = 1, kAvx512 = 2 };
inline constexpr EnumNames<Isa, 3> kIsaNames{
    {{"baseline", Isa::kBaseline}, {"avx2", Isa::kAvx2}, {"avx512", Isa::kAvx512}}};
constexpr std::string_view isaName(Isa i) { return enumName(kIsaNames, i); }

// The best tier this CPU and OS run (asked once per process).
Isa cpuIsa();
// The tier the code runs: min(cpuIsa(), limit).
Isa activeIsa();
inline bool isaAtLeast(Isa i) { return static_cast<int>(activeIsa()) >= static_cast<int>(i); }
// Caps the tier for the rest of the process (kAvx512 lifts the cap). Not for use while
// another thread runs vector code: set it before work starts.
void setIsaLimit(Isa limit);
// "baseline", "avx2" or "avx512" (as LIGHTLINK_ISA and --isa take it), or an error naming it.
Expected<Isa> parseIsa(std::string_view name);
// Whether LL_ISA_CLONES builds per-tier clones in this build (GCC on x86-64); elsewhere each
// tier runs the baseline code.
bool isaClonesBuilt();

}  // namespace lightlink

// LL_ISA_CLONES(Ret, name, (params...), (args...), impl): defines `Ret name(params...)`
// running `impl(args...)` compiled for the active tier. `impl` should be always_inline
// (LL_ISA_INLINE), so that each clone compiles it for its own target.
#define LL_ISA_INLINE __attribute__((always_inline)) inline
#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__)
#define LL_ISA_CLONES(Ret, name, PARAMS, ARGS, impl)                                                       \
  __attribute__((target("arch=x86-64-v4"), optimize("fp-contract=off"))) Ret name##_avx512 PARAMS {       \
    return impl ARGS;                                                                                      \
  }                                                                                                        \
  __attribute__((target("avx2,fma,f16c"), optimize("fp-contract=off"))) Ret name##_avx2 PARAMS {         \
    return impl ARGS;                                                                                      \
  }                                                                                                        \
  __attribute__((optimize("fp-contract=off"))) Ret name##_baseline PARAMS { return impl ARGS; }            \
  Ret name PARAMS {                                                                                        \
    switch (::lightlink::activeIsa()) {                                                                    \
      case ::lightlink::Isa::kAvx512: return name##_avx512 ARGS;                                          \
      case ::lightlink::Isa::kAvx2: return name##_avx2 ARGS;                                              \
      default: return name##_baseline ARGS;                                                                \
    }                                                                                                      \
  }
#else
#define LL_ISA_CLONES(Ret, name, PARAMS, ARGS, impl) \
  Ret name PARAMS { return impl ARGS; }
#endif
