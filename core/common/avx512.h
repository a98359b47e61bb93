// Kernels written with AVX-512 intrinsics (links: hit credit, the cut's splits) next to a
// scalar version that gives the same bits, the one to run chosen at run time: the target
// attribute those kernels are compiled with and the mask of a vector's first lanes. The project builds for the x86-64 baseline; whether such code runs is
// isaAtLeast(Isa::kAvx512) (isa.h), and LL_ISA_CLONES is the way for loops written on GCC
// vectors instead of intrinsics.
//
// LL_AVX512 is 1 where such kernels are compiled (x86-64 with GCC or Clang), else 0.
// LL_AVX512_FN marks a function that uses them: AVX-512 F, BW, VL and DQ, with contraction
// off under GCC (AVX-512 implies FMA to GCC, which fuses a * b + c even across intrinsics:
// a dot product would then round differently from the scalar kernel's; Clang does not
// contract across intrinsic calls).
#pragma once

#include <cstddef>

#include "core/common/isa.h"

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
// GCC 12 warns inside its own AVX-512 headers (the _mm512_undefined_* they start from, GCC
// bug 105593, fixed in 13): the warning is about the header, not its users' code, and it is
// raised where the intrinsics are inlined, so it stays off for the rest of the including file.
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#pragma GCC diagnostic ignored "-Wuninitialized"
#endif
#include <immintrin.h>
#define LL_AVX512 1
#if defined(__clang__)
#define LL_AVX512_FN __attribute__((target("avx512f,avx512bw,avx512vl,avx512dq")))
#else
#define LL_AVX512_FN __attribute__((target("avx512f,avx512bw,avx512vl,avx512dq"), optimize("fp-contract=off")))
#endif
#else
#define LL_AVX512 0
#endif

namespace lightlink {

#if LL_AVX512
// The first min(n, 16) lanes of a 16-lane vector: the mask of a loop's last, partial step.
inline __mmask16 firstLanes(std::size_t n) {
  return n >= 16 ? __mmask16(0xffff) : static_cast<__mmask16>((1u << n) - 1u);
}
#endif

}  // namespace lightlink
