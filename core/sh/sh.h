// Spherical harmonics: the one SH convention of lightlink (docs/sh.md states it for engines).
//
// Real orthonormal SH without the Condon-Shortley phase, bands l = 0..L-1 for L = 1..4
// "bands" (1, 4, 9, 16 coefficients), coefficient index i = l*l + l + m, m = -l..l. The basis
// is a polynomial in the components of a *unit* world-space direction (x, y, z as they are;
// no axis swizzle, so z is not "up" for the glTF y-up world, which SH does not care about).
// Stored coefficients are plain projections of radiance, L_lm = integral L(w) Y_lm(w) dw,
// nothing pre-scaled: a constant radiance L has L_00 = L * sqrt(4 pi). Turning radiance into
// irradiance multiplies band l by the clamped-cosine zonal factor A_l = {pi, 2pi/3, pi/4, 0};
// a normalised Blinn-Phong lobe multiplies band l by s_l(n) of seed 000 appendix B.
//
// Types are coefficient-contiguous float arrays (`Sh<B>` scalar, `ShRgb<B>` three planar
// channels), so band loops vectorise and a cache or link is a flat run of floats. The
// templates are for hot loops whose band count is known at compile time; the runtime-band
// functions on raw float pointers are for data whose band count is a bake parameter.
#pragma once

#include <array>
#include <cmath>
#include <numbers>

#include <glm/glm.hpp>

namespace lightlink::sh {

inline constexpr int kMaxBands = 4;
inline constexpr int kMaxCoeffs = kMaxBands * kMaxBands;

constexpr int coeffCount(int bands) { return bands * bands; }
constexpr int index(int l, int m) { return l * l + l + m; }
// The band l of coefficient index i (i in [0, 16)).
constexpr int bandOf(int i) { return i < 1 ? 0 : i < 4 ? 1 : i < 9 ? 2 : 3; }

// Normalisation constants K_lm times the integer factor of each polynomial (docs/sh.md lists
// the same numbers; tests/sh checks orthonormality numerically).
inline constexpr float kY00 = 0.282094791773878f;   // 1 / (2 sqrt(pi))
inline constexpr float kY1 = 0.488602511902920f;    // sqrt(3 / (4 pi))          y, z, x
inline constexpr float kY2Cross = 1.092548430592079f;  // sqrt(15 / (4 pi))      xy, yz, xz
inline constexpr float kY20 = 0.315391565252520f;   // sqrt(5 / (16 pi))          (3z^2 - 1)
inline constexpr float kY22 = 0.546274215296040f;   // sqrt(15 / (16 pi))         (x^2 - y^2)
inline constexpr float kY33 = 0.590043589926644f;   // sqrt(35 / (32 pi))  y(3x^2-y^2), x(x^2-3y^2)
inline constexpr float kY3Xyz = 2.890611442640554f; // sqrt(105 / (4 pi))         xyz
inline constexpr float kY31 = 0.457045799464466f;   // sqrt(21 / (32 pi))  y(5z^2-1), x(5z^2-1)
inline constexpr float kY30 = 0.373176332590115f;   // sqrt(7 / (16 pi))          z(5z^2 - 3)
inline constexpr float kY32 = 1.445305721320277f;   // sqrt(105 / (16 pi))        z(x^2 - y^2)

// Clamped-cosine zonal factors A_l: irradiance E(n) = sum_lm A_l L_lm Y_lm(n) for radiance
// SH L (Ramamoorthi & Hanrahan 2001). Band 3 is exactly 0 (odd bands > 1 vanish).
inline constexpr std::array<float, kMaxBands> kIrradianceBandFactors = {
    std::numbers::pi_v<float>, 2.0f * std::numbers::pi_v<float> / 3.0f,
    std::numbers::pi_v<float> / 4.0f, 0.0f};

// ---- basis ---------------------------------------------------------------------------

// Y_i(dir) for i < Bands*Bands; `dir` must be unit length (the band-2/3 polynomials use
// x^2 + y^2 + z^2 = 1). No trigonometry, no branches.
template <int Bands>
inline void evalBasis(const glm::vec3& dir, float* out) {
  static_assert(Bands >= 1 && Bands <= kMaxBands);
  const float x = dir.x, y = dir.y, z = dir.z;
  out[0] = kY00;
  if constexpr (Bands >= 2) {
    out[1] = kY1 * y;
    out[2] = kY1 * z;
    out[3] = kY1 * x;
  }
  if constexpr (Bands >= 3) {
    const float xx = x * x, yy = y * y, zz = z * z;
    out[4] = kY2Cross * x * y;
    out[5] = kY2Cross * y * z;
    out[6] = kY20 * (3.0f * zz - 1.0f);
    out[7] = kY2Cross * x * z;
    out[8] = kY22 * (xx - yy);
    if constexpr (Bands >= 4) {
      out[9] = kY33 * y * (3.0f * xx - yy);
      out[10] = kY3Xyz * x * y * z;
      out[11] = kY31 * y * (5.0f * zz - 1.0f);
      out[12] = kY30 * z * (5.0f * zz - 3.0f);
      out[13] = kY31 * x * (5.0f * zz - 1.0f);
      out[14] = kY32 * z * (xx - yy);
      out[15] = kY33 * x * (xx - 3.0f * yy);
    }
  }
}

// The basis as polynomial times constant: Y_i(dir) = kBasisScale[i] * basisPolynomial_i(dir).
// A sum of Y_i over many directions is then the constant times a sum of polynomials, which
// costs a few multiplies per direction instead of one per coefficient (link generation
// projects ~1000 hit directions per cache this way). Band 0's polynomial is 1: the sum is
// the direction count, which callers usually know.
inline constexpr std::array<float, kMaxCoeffs> kBasisScale = {
    kY00, kY1, kY1, kY1, kY2Cross, kY2Cross, kY20, kY2Cross, kY22,
    kY33, kY3Xyz, kY31, kY30, kY31, kY32, kY33};

// The same polynomials for any arithmetic type T with float's operators (float, or a GCC
// vector of floats: link generation evaluates 8 directions at once). One expression for
// both, so a lane of the vector form gives the scalar form's bits (with no FMA contraction,
// which lightlink's targets do not enable). out[0] (band 0's polynomial, 1) is not written.
template <int Bands, typename T>
inline void evalBasisPolynomialOf(const T& x, const T& y, const T& z, T* out) {
  static_assert(Bands >= 1 && Bands <= kMaxBands);
  if constexpr (Bands >= 2) {
    out[1] = y;
    out[2] = z;
    out[3] = x;
  }
  if constexpr (Bands >= 3) {
    const T xx = x * x, yy = y * y, zz = z * z;
    out[4] = x * y;
    out[5] = y * z;
    out[6] = 3.0f * zz - 1.0f;
    out[7] = x * z;
    out[8] = xx - yy;
    if constexpr (Bands >= 4) {
      out[9] = y * (3.0f * xx - yy);
      out[10] = x * y * z;
      out[11] = y * (5.0f * zz - 1.0f);
      out[12] = z * (5.0f * zz - 3.0f);
      out[13] = x * (5.0f * zz - 1.0f);
      out[14] = z * (xx - yy);
      out[15] = x * (xx - 3.0f * yy);
    }
  }
}

template <int Bands>
inline void evalBasisPolynomial(const glm::vec3& dir, float* out) {
  out[0] = 1.0f;
  evalBasisPolynomialOf<Bands, float>(dir.x, dir.y, dir.z, out);
}

// ---- value types ---------------------------------------------------------------------

// One scalar SH function, coefficients contiguous.
template <int Bands>
struct Sh {
  static_assert(Bands >= 1 && Bands <= kMaxBands);
  static constexpr int kBands = Bands;
  static constexpr int kCount = Bands * Bands;
  std::array<float, kCount> c{};
};

// An RGB SH function as three planar channels: c[channel][i]. Planar (not interleaved RGB)
// so that per-channel dot products and band scalings are straight float loops.
template <int Bands>
struct ShRgb {
  static_assert(Bands >= 1 && Bands <= kMaxBands);
  static constexpr int kBands = Bands;
  static constexpr int kCount = Bands * Bands;
  std::array<std::array<float, kCount>, 3> c{};

  ShRgb& operator+=(const ShRgb& o) {
    for (int ch = 0; ch < 3; ++ch)
      for (int i = 0; i < kCount; ++i) c[ch][i] += o.c[ch][i];
    return *this;
  }
  ShRgb& operator*=(float s) {
    for (auto& channel : c)
      for (float& v : channel) v *= s;
    return *this;
  }
};

// ---- projection ----------------------------------------------------------------------

// Monte Carlo / quadrature projection step: acc += weighted_value * Y(dir), where
// weighted_value = f(dir) * w (w = quadrature weight or 1/(N pdf)). `dir` unit length.
template <int Bands>
inline void projectAdd(Sh<Bands>& acc, const glm::vec3& dir, float weighted_value) {
  float y[Bands * Bands];
  evalBasis<Bands>(dir, y);
  for (int i = 0; i < Bands * Bands; ++i) acc.c[i] += weighted_value * y[i];
}

template <int Bands>
inline void projectAdd(ShRgb<Bands>& acc, const glm::vec3& dir, const glm::vec3& weighted_value) {
  float y[Bands * Bands];
  evalBasis<Bands>(dir, y);
  for (int i = 0; i < Bands * Bands; ++i) {
    acc.c[0][i] += weighted_value.x * y[i];
    acc.c[1][i] += weighted_value.y * y[i];
    acc.c[2][i] += weighted_value.z * y[i];
  }
}

// ---- evaluation ----------------------------------------------------------------------

// sum_i c_i Y_i(dir): the reconstructed function itself (may be negative: ringing).
template <int Bands>
inline float evaluate(const Sh<Bands>& f, const glm::vec3& dir) {
  float y[Bands * Bands];
  evalBasis<Bands>(dir, y);
  float s = 0.0f;
  for (int i = 0; i < Bands * Bands; ++i) s += f.c[i] * y[i];
  return s;
}

template <int Bands>
inline glm::vec3 evaluate(const ShRgb<Bands>& f, const glm::vec3& dir) {
  float y[Bands * Bands];
  evalBasis<Bands>(dir, y);
  glm::vec3 s(0.0f);
  for (int i = 0; i < Bands * Bands; ++i) s += glm::vec3(f.c[0][i], f.c[1][i], f.c[2][i]) * y[i];
  return s;
}

// sum_lm factors[l] * c_lm * Y_lm(dir): evaluation after a per-band (zonal) convolution.
template <int Bands>
inline float evaluateConvolved(const Sh<Bands>& f, const glm::vec3& dir,
                               const std::array<float, kMaxBands>& band_factors) {
  float y[Bands * Bands];
  evalBasis<Bands>(dir, y);
  float s = 0.0f;
  for (int l = 0; l < Bands; ++l) {
    float band = 0.0f;
    for (int i = l * l; i < (l + 1) * (l + 1); ++i) band += f.c[i] * y[i];
    s += band_factors[l] * band;
  }
  return s;
}

template <int Bands>
inline glm::vec3 evaluateConvolved(const ShRgb<Bands>& f, const glm::vec3& dir,
                                   const std::array<float, kMaxBands>& band_factors) {
  float y[Bands * Bands];
  evalBasis<Bands>(dir, y);
  glm::vec3 s(0.0f);
  for (int l = 0; l < Bands; ++l) {
    glm::vec3 band(0.0f);
    for (int i = l * l; i < (l + 1) * (l + 1); ++i)
      band += glm::vec3(f.c[0][i], f.c[1][i], f.c[2][i]) * y[i];
    s += band_factors[l] * band;
  }
  return s;
}

// Irradiance (W/m^2 for radiance in W/(m^2 sr), or the same photometric pair) at a surface
// with unit normal n lit by the radiance SH `radiance`: E(n) = sum A_l L_lm Y_lm(n). Clamped
// at 0 because a truncated series rings negative behind strong directional light.
template <int Bands>
inline float irradiance(const Sh<Bands>& radiance, const glm::vec3& n) {
  return glm::max(evaluateConvolved(radiance, n, kIrradianceBandFactors), 0.0f);
}

template <int Bands>
inline glm::vec3 irradiance(const ShRgb<Bands>& radiance, const glm::vec3& n) {
  return glm::max(evaluateConvolved(radiance, n, kIrradianceBandFactors), glm::vec3(0.0f));
}

// Per-band factors s_l(n) of a normalised Blinn-Phong lobe (n+1)/(2 pi) cos^n (seed 000
// appendix B): integral L(w) (n+1)/(2pi) max(0, <w, d>)^n dw = sum s_l(n) L_lm Y_lm(d).
// s_0 = 1, s_1 = (n+1)/(n+2), s_l = s_{l-2} (n+2-l)/(n+1+l). For n = 1, pi * s_l = A_l.
std::array<float, kMaxBands> phongBandFactors(float exponent);

// The lobe-weighted mean radiance around `dir` (unit): what a Blinn-Phong specular term of
// exponent n reads from radiance SH, clamped at 0.
template <int Bands>
inline glm::vec3 phongLobe(const ShRgb<Bands>& radiance, const glm::vec3& dir, float exponent) {
  return glm::max(evaluateConvolved(radiance, dir, phongBandFactors(exponent)), glm::vec3(0.0f));
}

// ---- zonal functions and windows -----------------------------------------------------

// Zonal coefficients z_l = integral f(<w, z>) Y_l0(w) dw of common axial functions.
// Clamped cosine max(0, cos): {sqrt(pi)/2, sqrt(pi/3), sqrt(5 pi)/8, 0}.
std::array<float, kMaxBands> clampedCosineZonal();
// Indicator of a cone of half-angle `half_angle_rad` (the SH of a disc seen from afar).
std::array<float, kMaxBands> coneZonal(float half_angle_rad);

// Rotates a zonal function onto the unit axis `axis` (seed 000 eq. 8):
// c_lm = sqrt(4 pi / (2l+1)) z_l Y_lm(axis).
template <int Bands>
inline Sh<Bands> rotateZonal(const std::array<float, kMaxBands>& zonal, const glm::vec3& axis) {
  Sh<Bands> out;
  evalBasis<Bands>(axis, out.c.data());
  for (int i = 0; i < Bands * Bands; ++i) {
    const int l = bandOf(i);
    out.c[i] *= std::sqrt(4.0f * std::numbers::pi_v<float> / float(2 * l + 1)) * zonal[l];
  }
  return out;
}

// Windowing against ringing (Sloan, "Stupid SH tricks"): per-band attenuation w_l with
// window width `width` (> 0; usually the band count). Hanning: (1 + cos(pi l / width)) / 2;
// Lanczos sigma: sinc(l / width). w_0 = 1 always, so band 0 (the mean) is never changed.
enum class Window { kNone, kHanning, kLanczos };
std::array<float, kMaxBands> windowFactors(Window window, float width);

template <int Bands>
inline void scaleBands(Sh<Bands>& f, const std::array<float, kMaxBands>& band_factors) {
  for (int i = 0; i < Bands * Bands; ++i) f.c[i] *= band_factors[bandOf(i)];
}
template <int Bands>
inline void scaleBands(ShRgb<Bands>& f, const std::array<float, kMaxBands>& band_factors) {
  for (auto& channel : f.c)
    for (int i = 0; i < Bands * Bands; ++i) channel[i] *= band_factors[bandOf(i)];
}

// ---- runtime band count (flat float arrays, bands in [1, 4]) -------------------------

void evalBasis(int bands, const glm::vec3& dir, float* out);
// coeffs[i] += weighted_value * Y_i(dir)
void projectAdd(int bands, const glm::vec3& dir, float weighted_value, float* coeffs);
float evaluate(int bands, const float* coeffs, const glm::vec3& dir);
// max(0, sum A_l c_lm Y_lm(n)) for radiance coefficients `coeffs`.
float irradiance(int bands, const float* radiance, const glm::vec3& n);

}  // namespace lightlink::sh
