#include "core/common/half.h"

#include "core/common/isa.h"

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
#include <cpuid.h>
#include <immintrin.h>
#define LL_HALF_F16C 1
#endif

namespace lightlink {
namespace {

std::size_t scalarRange(const float* src, half_bits* dst, std::size_t n) {
  std::size_t clamped = 0;
  for (std::size_t i = 0; i < n; ++i) {
    bool c = false;
    dst[i] = toHalfSaturating(src[i], c);
    clamped += c ? 1 : 0;
  }
  return clamped;
}

#ifdef LL_HALF_F16C
// Imath converts with round-to-nearest-even, as F16C does with _MM_FROUND_TO_NEAREST_INT
// (Imath itself uses F16C when compiled for it), so finite values agree bit for bit. A
// block holding a NaN takes the scalar path: the two keep different NaN payload bits.
__attribute__((target("avx,f16c"))) std::size_t f16cRange(const float* src, half_bits* dst, std::size_t n) {
  const __m256 max = _mm256_set1_ps(kHalfMax), lowest = _mm256_set1_ps(-kHalfMax);
  const __m256 abs_mask = _mm256_castsi256_ps(_mm256_set1_epi32(0x7fffffff));
  std::size_t clamped = 0, i = 0;
  for (; i + 8 <= n; i += 8) {
    const __m256 v = _mm256_loadu_ps(src + i);
    if (_mm256_movemask_ps(_mm256_cmp_ps(v, v, _CMP_UNORD_Q)) != 0) {
      clamped += scalarRange(src + i, dst + i, 8);
      continue;
    }
    const int over = _mm256_movemask_ps(_mm256_cmp_ps(_mm256_and_ps(v, abs_mask), max, _CMP_GT_OQ));
    clamped += static_cast<std::size_t>(__builtin_popcount(static_cast<unsigned>(over)));
    const __m256 c = _mm256_min_ps(_mm256_max_ps(v, lowest), max);
    _mm_storeu_si128(reinterpret_cast<__m128i*>(dst + i), _mm256_cvtps_ph(c, _MM_FROUND_TO_NEAREST_INT | _MM_FROUND_NO_EXC));
  }
  return clamped + scalarRange(src + i, dst + i, n - i);
}

#endif

}  // namespace

std::size_t toHalfSaturating(std::span<const float> src, half_bits* dst) {
#ifdef LL_HALF_F16C
  if (isaAtLeast(Isa::kAvx2)) return f16cRange(src.data(), dst, src.size());
#endif
  return scalarRange(src.data(), dst, src.size());
}

}  // namespace lightlink
