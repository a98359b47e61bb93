#include "core/sh/sh.h"

#include <algorithm>
#include <cmath>

#include "core/common/check.h"

namespace lightlink::sh {
namespace {
constexpr double kPi = std::numbers::pi;
}  // namespace

std::array<float, kMaxBands> phongBandFactors(float exponent) {
  // Appendix B recurrence, in double so large exponents (n ~ 1e4) keep their precision.
  const double n = exponent;
  std::array<double, kMaxBands> s{};
  s[0] = 1.0;
  s[1] = (n + 1.0) / (n + 2.0);
  for (int l = 2; l < kMaxBands; ++l) s[l] = s[l - 2] * (n + 2.0 - l) / (n + 1.0 + l);
  return {float(s[0]), float(s[1]), float(s[2]), float(s[3])};
}

std::array<float, kMaxBands> clampedCosineZonal() {
  // 2 pi * integral_0^1 z * P_l-polynomial(z) dz for each band's zonal polynomial.
  return {float(kPi * kY00), float(2.0 * kPi * kY1 / 3.0), float(kPi * kY20 / 2.0), 0.0f};
}

std::array<float, kMaxBands> coneZonal(float half_angle_rad) {
  // 2 pi * integral_{cos a}^1 Y_l0(z) dz, with Y_l0 the band's zonal polynomial in z.
  const double c = std::cos(double(half_angle_rad));
  const double c2 = c * c;
  return {float(2.0 * kPi * kY00 * (1.0 - c)), float(kPi * kY1 * (1.0 - c2)),
          float(2.0 * kPi * kY20 * (c - c2 * c)),
          float(2.0 * kPi * kY30 * (-0.25 - 1.25 * c2 * c2 + 1.5 * c2))};
}

std::array<float, kMaxBands> windowFactors(Window window, float width) {
  LL_CHECK(width > 0.0f);
  std::array<float, kMaxBands> w{1.0f, 1.0f, 1.0f, 1.0f};
  for (int l = 1; l < kMaxBands; ++l) {
    const double t = double(l) / double(width);
    switch (window) {
      case Window::kNone: break;
      case Window::kHanning: w[l] = t >= 1.0 ? 0.0f : float(0.5 * (1.0 + std::cos(kPi * t))); break;
      case Window::kLanczos: w[l] = t >= 1.0 ? 0.0f : float(std::sin(kPi * t) / (kPi * t)); break;
    }
  }
  return w;
}

void evalBasis(int bands, const glm::vec3& dir, float* out) {
  switch (bands) {
    case 1: evalBasis<1>(dir, out); return;
    case 2: evalBasis<2>(dir, out); return;
    case 3: evalBasis<3>(dir, out); return;
    case 4: evalBasis<4>(dir, out); return;
    default: LL_CHECK(bands >= 1 && bands <= kMaxBands);
  }
}

void projectAdd(int bands, const glm::vec3& dir, float weighted_value, float* coeffs) {
  float y[kMaxCoeffs];
  evalBasis(bands, dir, y);
  for (int i = 0; i < bands * bands; ++i) coeffs[i] += weighted_value * y[i];
}

float evaluate(int bands, const float* coeffs, const glm::vec3& dir) {
  float y[kMaxCoeffs];
  evalBasis(bands, dir, y);
  float s = 0.0f;
  for (int i = 0; i < bands * bands; ++i) s += coeffs[i] * y[i];
  return s;
}

float irradiance(int bands, const float* radiance, const glm::vec3& n) {
  float y[kMaxCoeffs];
  evalBasis(bands, n, y);
  float s = 0.0f;
  for (int i = 0; i < bands * bands; ++i) s += kIrradianceBandFactors[bandOf(i)] * radiance[i] * y[i];
  return std::max(s, 0.0f);
}

}  // namespace lightlink::sh
