#include "core/relight/cache_lighting.h"

#include <immintrin.h>
#if defined(__x86_64__) || defined(__i386__)
#include <cpuid.h>
#endif

#include <algorithm>
#include <cstring>

#include "core/common/half.h"
#include "core/relight/relight.h"
#include "core/sh/sh.h"

namespace lightlink::relight {

void capBandFactors(float omega_over_pi, float* k) {
  // Cap of solid angle omega around the axis: cos(half angle) c = 1 - omega / (2 pi), and
  // omega = pi * omega_over_pi. Integrating Y_l0 over the cap and rotating (seed 000 eq. 8)
  // gives per-band factors polynomial in c (the 1/pi of F = SH(V/pi) folded in):
  //   k0 = 2 (1 - c), k1 = 1 - c^2, k2 = c (1 - c^2), k3 = -(1 - c^2)(1 - 5 c^2) / 4.
  const float c = std::clamp(1.0f - 0.5f * omega_over_pi, -1.0f, 1.0f);
  const float s = 1.0f - c * c;
  k[0] = 2.0f * (1.0f - c);
  k[1] = s;
  k[2] = c * s;
  k[3] = -0.25f * s * (1.0f - 5.0f * c * c);
}

namespace detail {

void lightCacheProjectedScalar(const links::LinksView& view, std::size_t cache, int bands,
                               const NodeRadiance& node, float* out) {
  const int nc = bands * bands;
  const int stride = view.bands * view.bands;
  float acc[3][sh::kMaxCoeffs] = {};
  for (std::uint32_t k = view.offsets[cache]; k < view.offsets[cache + 1]; ++k) {
    const std::uint32_t n = view.node[k];
    const float br = node.rgbx[4 * n], bg = node.rgbx[4 * n + 1], bb = node.rgbx[4 * n + 2];
    const half_bits* c = view.coeffs.data() + std::size_t(k) * stride;
    for (int i = 0; i < nc; ++i) {
      const float f = fromHalf(c[i]);
      acc[0][i] += br * f;
      acc[1][i] += bg * f;
      acc[2][i] += bb * f;
    }
  }
  for (int ch = 0; ch < 3; ++ch) std::memcpy(out + ch * nc, acc[ch], sizeof(float) * nc);
}

void lightCacheRuntimeScalar(const links::LinksView& view, std::size_t cache, int bands,
                             const NodeRadiance& node, float* out) {
  const int nc = bands * bands;
  float acc[3][sh::kMaxCoeffs] = {};
  float y[sh::kMaxCoeffs];
  float kl[sh::kMaxBands];
  for (std::uint32_t k = view.offsets[cache]; k < view.offsets[cache + 1]; ++k) {
    const std::uint32_t n = view.node[k];
    const glm::vec3 d = links::decodeOctahedral(view.direction[k]);
    capBandFactors(fromHalf(view.solid_angle[k]), kl);
    sh::evalBasis(bands, d, y);
    const float br = node.rgbx[4 * n], bg = node.rgbx[4 * n + 1], bb = node.rgbx[4 * n + 2];
    for (int i = 0; i < nc; ++i) {
      const float f = kl[sh::bandOf(i)] * y[i];
      acc[0][i] += br * f;
      acc[1][i] += bg * f;
      acc[2][i] += bb * f;
    }
  }
  for (int ch = 0; ch < 3; ++ch) std::memcpy(out + ch * nc, acc[ch], sizeof(float) * nc);
}

std::uint64_t streamLinkBytes(const links::LinksView& view, std::size_t cache_begin, std::size_t cache_end,
                              bool projected) {
  const std::size_t k0 = view.offsets[cache_begin], k1 = view.offsets[cache_end];
  std::uint64_t sum = 0;
  for (std::size_t k = k0; k < k1; ++k) sum += view.node[k];
  if (projected) {
    const std::size_t stride = std::size_t(view.bands) * view.bands;
    const half_bits* c = view.coeffs.data();
    for (std::size_t i = k0 * stride; i < k1 * stride; ++i) sum += c[i];
  } else {
    for (std::size_t k = k0; k < k1; ++k) sum += view.direction[k] + view.solid_angle[k];
  }
  return sum;
}

#if defined(__x86_64__) || defined(__i386__)
#define LL_AVX2 __attribute__((target("avx2,f16c,fma")))

namespace {

LL_AVX2 inline float hsum(__m256 v) {
  const __m128 lo = _mm256_castps256_ps128(v), hi = _mm256_extractf128_ps(v, 1);
  __m128 s = _mm_add_ps(lo, hi);
  s = _mm_add_ps(s, _mm_movehl_ps(s, s));
  s = _mm_add_ss(s, _mm_movehdup_ps(s));
  return _mm_cvtss_f32(s);
}

// Projected form, output coefficient count NC (1, 4, 9, 16). Per link: one broadcast of
// each channel's node radiosity and 8-wide fp16 -> float conversions of the coefficients;
// 8-wide accumulators keep all coefficients in registers (NC = 16: 6 ymm).
template <int NC>
LL_AVX2 void projectedKernel(const links::LinksView& view, std::size_t cache, const NodeRadiance& node, float* out) {
  const std::size_t stride = std::size_t(view.bands) * view.bands;
  const std::uint32_t k0 = view.offsets[cache], k1 = view.offsets[cache + 1];
  const half_bits* coeffs = view.coeffs.data();
  if constexpr (NC == 1) {
    float r = 0, g = 0, b = 0;
    for (std::uint32_t k = k0; k < k1; ++k) {
      const std::uint32_t n = view.node[k];
      const float f = _cvtsh_ss(coeffs[k * stride]);
      r += node.rgbx[4 * n] * f;
      g += node.rgbx[4 * n + 1] * f;
      b += node.rgbx[4 * n + 2] * f;
    }
    out[0] = r, out[1] = g, out[2] = b;
  } else if constexpr (NC == 4) {
    __m128 ar = _mm_setzero_ps(), ag = _mm_setzero_ps(), ab = _mm_setzero_ps();
    for (std::uint32_t k = k0; k < k1; ++k) {
      const std::uint32_t n = view.node[k];
      const __m128 f = _mm_cvtph_ps(_mm_loadl_epi64(reinterpret_cast<const __m128i*>(coeffs + k * stride)));
      const float* rgb = node.rgbx + 4 * std::size_t(n);
      ar = _mm_fmadd_ps(_mm_broadcast_ss(rgb), f, ar);
      ag = _mm_fmadd_ps(_mm_broadcast_ss(rgb + 1), f, ag);
      ab = _mm_fmadd_ps(_mm_broadcast_ss(rgb + 2), f, ab);
    }
    _mm_storeu_ps(out, ar);
    _mm_storeu_ps(out + 4, ag);
    _mm_storeu_ps(out + 8, ab);
  } else {
    static_assert(NC == 9 || NC == 16);
    __m256 a0r = _mm256_setzero_ps(), a0g = _mm256_setzero_ps(), a0b = _mm256_setzero_ps();
    __m256 a1r = _mm256_setzero_ps(), a1g = _mm256_setzero_ps(), a1b = _mm256_setzero_ps();
    __m128 t8 = _mm_setzero_ps();  // coefficient 8 of (R, G, B, -) when NC == 9
    for (std::uint32_t k = k0; k < k1; ++k) {
      const std::uint32_t n = view.node[k];
      const half_bits* c = coeffs + k * stride;
      const float* rgb = node.rgbx + 4 * std::size_t(n);
      const __m256 br = _mm256_broadcast_ss(rgb), bg = _mm256_broadcast_ss(rgb + 1), bb = _mm256_broadcast_ss(rgb + 2);
      // 16-byte load of coefficients 0..7: within the link for stride >= 9.
      const __m256 f0 = _mm256_cvtph_ps(_mm_loadu_si128(reinterpret_cast<const __m128i*>(c)));
      a0r = _mm256_fmadd_ps(br, f0, a0r);
      a0g = _mm256_fmadd_ps(bg, f0, a0g);
      a0b = _mm256_fmadd_ps(bb, f0, a0b);
      if constexpr (NC == 16) {
        const __m256 f1 = _mm256_cvtph_ps(_mm_loadu_si128(reinterpret_cast<const __m128i*>(c + 8)));
        a1r = _mm256_fmadd_ps(br, f1, a1r);
        a1g = _mm256_fmadd_ps(bg, f1, a1g);
        a1b = _mm256_fmadd_ps(bb, f1, a1b);
      } else {
        // One 4-wide FMA for the ninth coefficient of all three channels.
        t8 = _mm_fmadd_ps(_mm_loadu_ps(rgb), _mm_set1_ps(_cvtsh_ss(c[8])), t8);
      }
    }
    _mm256_storeu_ps(out, a0r);
    _mm256_storeu_ps(out + NC, a0g);
    _mm256_storeu_ps(out + 2 * NC, a0b);
    if constexpr (NC == 16) {
      _mm256_storeu_ps(out + 8, a1r);
      _mm256_storeu_ps(out + NC + 8, a1g);
      _mm256_storeu_ps(out + 2 * NC + 8, a1b);
    } else {
      alignas(16) float t[4];
      _mm_store_ps(t, t8);
      out[8] = t[0], out[NC + 8] = t[1], out[2 * NC + 8] = t[2];
    }
  }
}

// Runtime form: eight links per iteration, one per lane. Decode the octahedral directions,
// evaluate the cap band factors and the SH basis lane-wise, gather the node radiosity and
// accumulate bands^2 x 3 lane-vectors; one horizontal sum per coefficient at the end.
template <int Bands>
LL_AVX2 void runtimeKernel(const links::LinksView& view, std::size_t cache, const NodeRadiance& node, float* out) {
  constexpr int NC = Bands * Bands;
  const std::uint32_t k0 = view.offsets[cache], k1 = view.offsets[cache + 1];
  __m256 acc[3][NC];
  for (auto& ch : acc)
    for (auto& a : ch) a = _mm256_setzero_ps();
  const __m256 one = _mm256_set1_ps(1.0f), zero = _mm256_setzero_ps();
  const __m256 sign_mask = _mm256_set1_ps(-0.0f);
  const __m256 inv_q = _mm256_set1_ps(1.0f / 32767.0f);
  alignas(32) std::uint32_t tail_dir[8], tail_node[8];
  alignas(16) half_bits tail_omega[8];
  for (std::uint32_t k = k0; k < k1; k += 8) {
    const std::uint32_t count = std::min<std::uint32_t>(8, k1 - k);
    const std::uint32_t* dir_p = view.direction.data() + k;
    const std::uint32_t* node_p = view.node.data() + k;
    const half_bits* omega_p = view.solid_angle.data() + k;
    if (count < 8) {
      // Tail: padded copies with omega = 0 (k_l = 0) and node 0, so the extra lanes add 0.
      std::fill(std::begin(tail_dir), std::end(tail_dir), 0u);
      std::fill(std::begin(tail_node), std::end(tail_node), 0u);
      std::fill(std::begin(tail_omega), std::end(tail_omega), half_bits(0));
      std::copy(dir_p, dir_p + count, tail_dir);
      std::copy(node_p, node_p + count, tail_node);
      std::copy(omega_p, omega_p + count, tail_omega);
      dir_p = tail_dir, node_p = tail_node, omega_p = tail_omega;
    }
    const __m256i d = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(dir_p));
    __m256 x = _mm256_mul_ps(_mm256_cvtepi32_ps(_mm256_srai_epi32(_mm256_slli_epi32(d, 16), 16)), inv_q);
    __m256 y = _mm256_mul_ps(_mm256_cvtepi32_ps(_mm256_srai_epi32(d, 16)), inv_q);
    const __m256 ax = _mm256_andnot_ps(sign_mask, x), ay = _mm256_andnot_ps(sign_mask, y);
    __m256 z = _mm256_sub_ps(_mm256_sub_ps(one, ax), ay);
    const __m256 lower = _mm256_cmp_ps(z, zero, _CMP_LT_OQ);
    // Lower hemisphere fold: x' = (1 - |y|) sign(x), y' = (1 - |x|) sign(y); sign(+-0) = +.
    const __m256 fx = _mm256_or_ps(_mm256_sub_ps(one, ay), _mm256_and_ps(sign_mask, x));
    const __m256 fy = _mm256_or_ps(_mm256_sub_ps(one, ax), _mm256_and_ps(sign_mask, y));
    x = _mm256_blendv_ps(x, fx, lower);
    y = _mm256_blendv_ps(y, fy, lower);
    const __m256 inv_len =
        _mm256_div_ps(one, _mm256_sqrt_ps(_mm256_fmadd_ps(x, x, _mm256_fmadd_ps(y, y, _mm256_mul_ps(z, z)))));
    x = _mm256_mul_ps(x, inv_len), y = _mm256_mul_ps(y, inv_len), z = _mm256_mul_ps(z, inv_len);

    const __m256 w = _mm256_cvtph_ps(_mm_loadu_si128(reinterpret_cast<const __m128i*>(omega_p)));
    __m256 c = _mm256_fnmadd_ps(_mm256_set1_ps(0.5f), w, one);
    c = _mm256_max_ps(_mm256_set1_ps(-1.0f), _mm256_min_ps(one, c));
    const __m256 cc = _mm256_mul_ps(c, c);
    const __m256 s = _mm256_sub_ps(one, cc);
    __m256 f[NC];
    f[0] = _mm256_mul_ps(_mm256_set1_ps(2.0f * sh::kY00), _mm256_sub_ps(one, c));
    if constexpr (Bands >= 2) {
      const __m256 k1v = _mm256_mul_ps(_mm256_set1_ps(sh::kY1), s);
      f[1] = _mm256_mul_ps(k1v, y);
      f[2] = _mm256_mul_ps(k1v, z);
      f[3] = _mm256_mul_ps(k1v, x);
    }
    if constexpr (Bands >= 3) {
      const __m256 k2v = _mm256_mul_ps(c, s);
      const __m256 xx = _mm256_mul_ps(x, x), yy = _mm256_mul_ps(y, y), zz = _mm256_mul_ps(z, z);
      const __m256 kc = _mm256_mul_ps(k2v, _mm256_set1_ps(sh::kY2Cross));
      f[4] = _mm256_mul_ps(kc, _mm256_mul_ps(x, y));
      f[5] = _mm256_mul_ps(kc, _mm256_mul_ps(y, z));
      f[6] = _mm256_mul_ps(_mm256_mul_ps(k2v, _mm256_set1_ps(sh::kY20)),
                           _mm256_fmsub_ps(_mm256_set1_ps(3.0f), zz, one));
      f[7] = _mm256_mul_ps(kc, _mm256_mul_ps(x, z));
      f[8] = _mm256_mul_ps(_mm256_mul_ps(k2v, _mm256_set1_ps(sh::kY22)), _mm256_sub_ps(xx, yy));
      if constexpr (Bands >= 4) {
        const __m256 k3v = _mm256_mul_ps(_mm256_set1_ps(-0.25f),
                                         _mm256_mul_ps(s, _mm256_fnmadd_ps(_mm256_set1_ps(5.0f), cc, one)));
        const __m256 five_zz_m1 = _mm256_fmsub_ps(_mm256_set1_ps(5.0f), zz, one);
        f[9] = _mm256_mul_ps(_mm256_mul_ps(k3v, _mm256_set1_ps(sh::kY33)),
                             _mm256_mul_ps(y, _mm256_fmsub_ps(_mm256_set1_ps(3.0f), xx, yy)));
        f[10] = _mm256_mul_ps(_mm256_mul_ps(k3v, _mm256_set1_ps(sh::kY3Xyz)), _mm256_mul_ps(_mm256_mul_ps(x, y), z));
        f[11] = _mm256_mul_ps(_mm256_mul_ps(k3v, _mm256_set1_ps(sh::kY31)), _mm256_mul_ps(y, five_zz_m1));
        f[12] = _mm256_mul_ps(_mm256_mul_ps(k3v, _mm256_set1_ps(sh::kY30)),
                              _mm256_mul_ps(z, _mm256_fmsub_ps(_mm256_set1_ps(5.0f), zz, _mm256_set1_ps(3.0f))));
        f[13] = _mm256_mul_ps(_mm256_mul_ps(k3v, _mm256_set1_ps(sh::kY31)), _mm256_mul_ps(x, five_zz_m1));
        f[14] = _mm256_mul_ps(_mm256_mul_ps(k3v, _mm256_set1_ps(sh::kY32)), _mm256_mul_ps(z, _mm256_sub_ps(xx, yy)));
        f[15] = _mm256_mul_ps(_mm256_mul_ps(k3v, _mm256_set1_ps(sh::kY33)),
                              _mm256_mul_ps(x, _mm256_fnmadd_ps(_mm256_set1_ps(3.0f), yy, xx)));
      }
    }
    const __m256i n4 = _mm256_slli_epi32(_mm256_loadu_si256(reinterpret_cast<const __m256i*>(node_p)), 2);
    const __m256 br = _mm256_i32gather_ps(node.rgbx, n4, 4), bg = _mm256_i32gather_ps(node.rgbx + 1, n4, 4),
                 bb = _mm256_i32gather_ps(node.rgbx + 2, n4, 4);
    for (int i = 0; i < NC; ++i) {
      acc[0][i] = _mm256_fmadd_ps(br, f[i], acc[0][i]);
      acc[1][i] = _mm256_fmadd_ps(bg, f[i], acc[1][i]);
      acc[2][i] = _mm256_fmadd_ps(bb, f[i], acc[2][i]);
    }
  }
  for (int ch = 0; ch < 3; ++ch)
    for (int i = 0; i < NC; ++i) out[ch * NC + i] = hsum(acc[ch][i]);
}

}  // namespace

void lightCacheProjectedAvx2(const links::LinksView& view, std::size_t cache, int bands, const NodeRadiance& node,
                             float* out) {
  switch (bands) {
    case 1: return projectedKernel<1>(view, cache, node, out);
    case 2: return projectedKernel<4>(view, cache, node, out);
    case 3: return projectedKernel<9>(view, cache, node, out);
    default: return projectedKernel<16>(view, cache, node, out);
  }
}

void lightCacheRuntimeAvx2(const links::LinksView& view, std::size_t cache, int bands, const NodeRadiance& node,
                           float* out) {
  switch (bands) {
    case 1: return runtimeKernel<1>(view, cache, node, out);
    case 2: return runtimeKernel<2>(view, cache, node, out);
    case 3: return runtimeKernel<3>(view, cache, node, out);
    default: return runtimeKernel<4>(view, cache, node, out);
  }
}
#else
void lightCacheProjectedAvx2(const links::LinksView& view, std::size_t cache, int bands, const NodeRadiance& node,
                             float* out) {
  lightCacheProjectedScalar(view, cache, bands, node, out);
}
void lightCacheRuntimeAvx2(const links::LinksView& view, std::size_t cache, int bands, const NodeRadiance& node,
                           float* out) {
  lightCacheRuntimeScalar(view, cache, bands, node, out);
}
#endif

}  // namespace detail
}  // namespace lightlink::relight
