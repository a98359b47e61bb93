// Tests of the SH convention: orthonormality by exact quadrature, furnace, analytic zonal
// lobes, the known 3-band error of a directional light, clamping and windowing.
#include "core/sh/sh.h"

#include <cmath>
#include <numbers>
#include <random>
#include <vector>

#include <gtest/gtest.h>

namespace lightlink::sh {
namespace {

constexpr double kPi = std::numbers::pi;

// Gauss-Legendre nodes/weights on [a, b] (Newton on P_n, double precision).
struct Quadrature1d {
  std::vector<double> x, w;
};
Quadrature1d gaussLegendre(int n, double a, double b) {
  Quadrature1d q;
  for (int i = 0; i < n; ++i) {
    double z = std::cos(kPi * (i + 0.75) / (n + 0.5));
    double dp = 0.0;
    for (int it = 0; it < 100; ++it) {
      double p0 = 1.0, p1 = z;
      for (int k = 2; k <= n; ++k) {
        const double p2 = ((2.0 * k - 1.0) * z * p1 - (k - 1.0) * p0) / k;
        p0 = p1;
        p1 = p2;
      }
      dp = n * (z * p1 - p0) / (z * z - 1.0);
      const double dz = p1 / dp;
      z -= dz;
      if (std::abs(dz) < 1e-15) break;
    }
    q.x.push_back(0.5 * (a + b) + 0.5 * (b - a) * z);
    q.w.push_back((b - a) / ((1.0 - z * z) * dp * dp));
  }
  return q;
}

// Product rule over the spherical cap cos(theta) in [z0, 1] around `axis`: Gauss-Legendre in
// cos(theta) times an equally spaced azimuth. Exact (to rounding) for polynomials in the
// direction's components of degree < min(2*nz, nphi) in the axis frame.
struct Direction {
  glm::dvec3 dir;
  double weight;
};
std::vector<Direction> capQuadrature(glm::dvec3 axis, double z0, int nz, int nphi) {
  axis = glm::normalize(axis);
  const glm::dvec3 helper = std::abs(axis.x) < 0.9 ? glm::dvec3(1, 0, 0) : glm::dvec3(0, 1, 0);
  const glm::dvec3 t = glm::normalize(glm::cross(helper, axis));
  const glm::dvec3 b = glm::cross(axis, t);
  std::vector<Direction> out;
  const Quadrature1d qz = gaussLegendre(nz, z0, 1.0);
  for (int i = 0; i < nz; ++i) {
    const double z = qz.x[i];
    const double r = std::sqrt(std::max(0.0, 1.0 - z * z));
    for (int j = 0; j < nphi; ++j) {
      const double phi = 2.0 * kPi * (j + 0.5) / nphi;
      out.push_back({z * axis + r * std::cos(phi) * t + r * std::sin(phi) * b,
                     qz.w[i] * 2.0 * kPi / nphi});
    }
  }
  return out;
}

std::vector<double> basisD(glm::dvec3 d) {
  float y[kMaxCoeffs];
  evalBasis<4>(glm::vec3(d), y);
  return std::vector<double>(y, y + kMaxCoeffs);
}

glm::vec3 randomUnit(std::mt19937& rng) {
  std::normal_distribution<float> n(0.0f, 1.0f);
  glm::vec3 v;
  do v = glm::vec3(n(rng), n(rng), n(rng));
  while (glm::dot(v, v) < 1e-6f);
  return glm::normalize(v);
}

TEST(Sh, IndexConvention) {
  EXPECT_EQ(index(0, 0), 0);
  EXPECT_EQ(index(1, -1), 1);
  EXPECT_EQ(index(1, 1), 3);
  EXPECT_EQ(index(2, 0), 6);
  EXPECT_EQ(index(3, 3), 15);
  for (int l = 0; l < kMaxBands; ++l)
    for (int m = -l; m <= l; ++m) EXPECT_EQ(bandOf(index(l, m)), l);
  // Signs without Condon-Shortley phase: Y_1-1 ~ +y, Y_10 ~ +z, Y_11 ~ +x.
  float y[kMaxCoeffs];
  evalBasis<4>(glm::vec3(0, 1, 0), y);
  EXPECT_GT(y[1], 0.0f);
  evalBasis<4>(glm::vec3(0, 0, 1), y);
  EXPECT_GT(y[2], 0.0f);
  evalBasis<4>(glm::vec3(1, 0, 0), y);
  EXPECT_GT(y[3], 0.0f);
}

TEST(Sh, BasisIsScaleTimesPolynomial) {
  // What link generation sums instead of the basis itself, for every band count.
  std::mt19937 rng(11);
  std::normal_distribution<float> g(0.0f, 1.0f);
  for (int k = 0; k < 2000; ++k) {
    const glm::vec3 d = glm::normalize(glm::vec3(g(rng), g(rng), g(rng)));
    float y[kMaxCoeffs], p[kMaxCoeffs];
    evalBasis<4>(d, y);
    evalBasisPolynomial<4>(d, p);
    for (int i = 0; i < kMaxCoeffs; ++i) EXPECT_NEAR(kBasisScale[std::size_t(i)] * p[i], y[i], 2e-6f) << i;
    float p3[9];
    evalBasisPolynomial<3>(d, p3);
    for (int i = 0; i < 9; ++i) EXPECT_EQ(p3[i], p[i]) << i;
  }
}

TEST(Sh, PolynomialOfEightLanesEqualsTheScalarBitForBit) {
  // Link generation evaluates the polynomials 8 directions at a time (a GCC vector) in its
  // sky pass and sums those values into the links: each lane must be the scalar's bits.
  typedef float Lanes8 __attribute__((vector_size(32)));
  std::mt19937 rng(12);
  std::normal_distribution<float> g(0.0f, 1.0f);
  for (int k = 0; k < 250; ++k) {
    Lanes8 x, y, z;
    for (int l = 0; l < 8; ++l) {
      const glm::vec3 d = glm::normalize(glm::vec3(g(rng), g(rng), g(rng)));
      x[l] = d.x, y[l] = d.y, z[l] = d.z;
    }
    Lanes8 lanes[kMaxCoeffs];
    evalBasisPolynomialOf<4, Lanes8>(x, y, z, lanes);
    for (int l = 0; l < 8; ++l) {
      float p[kMaxCoeffs];
      evalBasisPolynomial<4>(glm::vec3(x[l], y[l], z[l]), p);
      for (int i = 1; i < kMaxCoeffs; ++i) EXPECT_EQ(lanes[i][l], p[i]) << "lane " << l << " coefficient " << i;
    }
  }
}

// The products Y_i Y_j have degree <= 6: 8 Gauss-Legendre nodes in z and 16 azimuths
// integrate them exactly, so the only error is float evaluation of the basis (~1e-7).
TEST(Sh, OrthonormalByExactQuadrature) {
  const auto quad = capQuadrature({0.3, -0.5, 0.8}, -1.0, 8, 16);
  for (int i = 0; i < kMaxCoeffs; ++i) {
    for (int j = 0; j < kMaxCoeffs; ++j) {
      double s = 0.0;
      for (const auto& q : quad) {
        const auto y = basisD(q.dir);
        s += q.weight * y[i] * y[j];
      }
      EXPECT_NEAR(s, i == j ? 1.0 : 0.0, 2e-6) << "i=" << i << " j=" << j;
    }
  }
}

// Also by plain Monte Carlo, so the quadrature helper is not the only witness.
TEST(Sh, OrthonormalByMonteCarlo) {
  std::mt19937 rng(7);
  const int n = 400000;
  std::vector<double> gram(kMaxCoeffs * kMaxCoeffs, 0.0);
  for (int k = 0; k < n; ++k) {
    const auto y = basisD(glm::dvec3(randomUnit(rng)));
    for (int i = 0; i < kMaxCoeffs; ++i)
      for (int j = 0; j < kMaxCoeffs; ++j) gram[i * kMaxCoeffs + j] += y[i] * y[j];
  }
  // Monte Carlo std error of each entry is <= ~3 * sqrt(4 pi) / sqrt(n) ~ 0.017 for the
  // peakiest band-3 products; 0.03 is > 4 sigma for the diagonal and off-diagonals alike.
  for (int i = 0; i < kMaxCoeffs; ++i)
    for (int j = 0; j < kMaxCoeffs; ++j)
      EXPECT_NEAR(gram[i * kMaxCoeffs + j] * 4.0 * kPi / n, i == j ? 1.0 : 0.0, 0.03)
          << "i=" << i << " j=" << j;
}

// White furnace: constant radiance L projects to L00 = L sqrt(4 pi), all else 0, and gives
// irradiance pi L for every normal.
TEST(Sh, FurnaceConstantRadiance) {
  const glm::vec3 radiance(1.7f, 0.25f, 3.0f);
  ShRgb<4> sh;
  for (const auto& q : capQuadrature({0, 0, 1}, -1.0, 8, 16))
    projectAdd(sh, glm::vec3(q.dir), radiance * float(q.weight));
  const float sqrt4pi = std::sqrt(4.0f * std::numbers::pi_v<float>);
  for (int ch = 0; ch < 3; ++ch) {
    EXPECT_NEAR(sh.c[ch][0], radiance[ch] * sqrt4pi, 1e-5f * radiance[ch] * sqrt4pi);
    for (int i = 1; i < kMaxCoeffs; ++i) EXPECT_NEAR(sh.c[ch][i], 0.0f, 1e-5f);
  }
  std::mt19937 rng(1);
  for (int k = 0; k < 200; ++k) {
    const glm::vec3 n = randomUnit(rng);
    const glm::vec3 e = irradiance(sh, n);
    for (int ch = 0; ch < 3; ++ch)
      EXPECT_NEAR(e[ch], std::numbers::pi_v<float> * radiance[ch], 2e-5f * radiance[ch] * 4.0f);
    Sh<3> g;
    for (int i = 0; i < 9; ++i) g.c[i] = sh.c[1][i];
    EXPECT_NEAR(irradiance(g, n), std::numbers::pi_v<float> * radiance.y, 1e-5f);
    EXPECT_NEAR(irradiance(3, g.c.data(), n), std::numbers::pi_v<float> * radiance.y, 1e-5f);
  }
}

TEST(Sh, ClampedCosineZonalMatchesAnalytic) {
  const auto z = clampedCosineZonal();
  EXPECT_NEAR(z[0], std::sqrt(kPi) / 2.0, 1e-6);
  EXPECT_NEAR(z[1], std::sqrt(kPi / 3.0), 1e-6);
  EXPECT_NEAR(z[2], std::sqrt(5.0 * kPi) / 8.0, 1e-6);
  EXPECT_NEAR(z[3], 0.0, 1e-7);
  // The irradiance factors are the same lobe after eq. 8: A_l = sqrt(4pi/(2l+1)) z_l.
  for (int l = 0; l < kMaxBands; ++l)
    EXPECT_NEAR(kIrradianceBandFactors[l], std::sqrt(4.0 * kPi / (2 * l + 1)) * z[l], 1e-6);
}

// Projecting max(0, <w, axis>) numerically around arbitrary axes equals the rotated zonal
// coefficients. The quadrature is over the hemisphere around the axis, where the integrand
// is a polynomial, so it is exact.
TEST(Sh, ClampedCosineProjectionMatchesRotatedZonal) {
  std::mt19937 rng(3);
  for (int trial = 0; trial < 8; ++trial) {
    const glm::vec3 axis = randomUnit(rng);
    Sh<4> numeric;
    for (const auto& q : capQuadrature(glm::dvec3(axis), 0.0, 8, 16))
      projectAdd(numeric, glm::vec3(q.dir), float(q.weight * glm::dot(q.dir, glm::dvec3(axis))));
    const Sh<4> analytic = rotateZonal<4>(clampedCosineZonal(), axis);
    for (int i = 0; i < kMaxCoeffs; ++i) EXPECT_NEAR(numeric.c[i], analytic.c[i], 2e-6f) << i;
  }
}

TEST(Sh, ConeZonalMatchesQuadrature) {
  for (float half_angle : {0.05f, 0.4f, 1.2f, 2.5f, 3.14159265f}) {
    Sh<4> numeric;
    for (const auto& q : capQuadrature({0, 0, 1}, std::cos(double(half_angle)), 8, 16))
      projectAdd(numeric, glm::vec3(q.dir), float(q.weight));
    const auto z = coneZonal(half_angle);
    for (int l = 0; l < kMaxBands; ++l) EXPECT_NEAR(z[l], numeric.c[index(l, 0)], 2e-6f) << l;
    // Solid angle of the cone is z_0 * sqrt(4 pi).
    EXPECT_NEAR(z[0] * std::sqrt(4.0 * kPi), 2.0 * kPi * (1.0 - std::cos(double(half_angle))), 1e-5);
  }
}

// Appendix B factors equal sqrt(4pi/(2l+1)) * (zonal projection of (n+1)/(2pi) cos^n).
TEST(Sh, PhongBandFactorsMatchQuadrature) {
  for (float n : {1.0f, 2.0f, 8.0f, 32.0f, 100.0f}) {
    const auto s = phongBandFactors(n);
    const int nodes = int(n) / 2 + 4;  // cos^n * P_3 has degree n + 3: exact with these nodes
    Sh<4> numeric;
    for (const auto& q : capQuadrature({0, 0, 1}, 0.0, nodes, 16))
      projectAdd(numeric, glm::vec3(q.dir),
                 float(q.weight * (n + 1.0) / (2.0 * kPi) * std::pow(q.dir.z, double(n))));
    for (int l = 0; l < kMaxBands; ++l)
      EXPECT_NEAR(s[l], std::sqrt(4.0 * kPi / (2 * l + 1)) * numeric.c[index(l, 0)], 2e-5)
          << "n=" << n << " l=" << l;
  }
  // n = 1 is the normalised cosine: pi * s_l = A_l. Large n tends to a delta: s_l -> 1.
  const auto s1 = phongBandFactors(1.0f);
  for (int l = 0; l < kMaxBands; ++l) EXPECT_NEAR(std::numbers::pi_v<float> * s1[l], kIrradianceBandFactors[l], 1e-6f);
  for (float f : phongBandFactors(1e5f)) EXPECT_NEAR(f, 1.0f, 1e-3f);
}

// A single directional light of normal irradiance E0 from direction d has L_lm = E0 Y_lm(d).
// The truncated clamped cosine with 3 bands is 3/32 + t/2 + 15/32 t^2 (t = <n, d>), so the
// largest irradiance error is exactly 3/32 E0 (at t = 0); band 3 adds nothing (A_3 = 0).
// With 2 bands it is 1/4 + t/2, error 1/4 E0 (at t = +-1).
TEST(Sh, DirectionalLightWithinKnownTruncationError) {
  const float e0 = 2.5f;
  std::mt19937 rng(11);
  for (int trial = 0; trial < 4; ++trial) {
    const glm::vec3 d = randomUnit(rng);
    Sh<4> l4;
    projectAdd(l4, d, e0);
    Sh<3> l3;
    projectAdd(l3, d, e0);
    Sh<2> l2;
    projectAdd(l2, d, e0);
    float max_err3 = 0.0f, max_err4 = 0.0f, max_err2 = 0.0f;
    for (int k = 0; k < 4000; ++k) {
      glm::vec3 n = randomUnit(rng);
      if (k == 0) n = glm::normalize(glm::cross(d, randomUnit(rng)));  // t = 0: the worst case
      const float exact = e0 * std::max(0.0f, glm::dot(n, d));
      max_err3 = std::max(max_err3, std::abs(irradiance(l3, n) - exact));
      max_err4 = std::max(max_err4, std::abs(irradiance(l4, n) - exact));
      max_err2 = std::max(max_err2, std::abs(irradiance(l2, n) - exact));
    }
    EXPECT_LE(max_err3, e0 * 3.0f / 32.0f + 1e-5f);
    EXPECT_GE(max_err3, e0 * 3.0f / 32.0f - 1e-4f);
    EXPECT_NEAR(max_err4, max_err3, 1e-5f);
    EXPECT_LE(max_err2, e0 * 0.25f + 1e-5f);
    EXPECT_GE(max_err2, e0 * 0.25f * 0.98f);
  }
}

// Strong directional lights make the truncated irradiance ring negative behind them; the
// returned value must still be >= 0 (and the unclamped series must really go negative, or
// this test would not test anything).
TEST(Sh, IrradianceNeverNegative) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  float min_unclamped = 0.0f;
  for (int trial = 0; trial < 50; ++trial) {
    ShRgb<4> sh;
    projectAdd(sh, randomUnit(rng), glm::vec3(10.0f, 5.0f, 1.0f));
    if (trial % 2) {
      for (auto& ch : sh.c)
        for (int i = 1; i < kMaxCoeffs; ++i) ch[i] += u(rng);
    }
    for (int k = 0; k < 500; ++k) {
      const glm::vec3 n = randomUnit(rng);
      const glm::vec3 e = irradiance(sh, n);
      EXPECT_GE(std::min({e.x, e.y, e.z}), 0.0f);
      Sh<4> red;
      red.c = sh.c[0];
      EXPECT_GE(irradiance(red, n), 0.0f);
      EXPECT_GE(irradiance(4, red.c.data(), n), 0.0f);
      EXPECT_GE(std::min({phongLobe(sh, n, 20.0f).x, phongLobe(sh, n, 20.0f).y}), 0.0f);
      min_unclamped = std::min(min_unclamped, evaluateConvolved(red, n, kIrradianceBandFactors));
    }
  }
  EXPECT_LT(min_unclamped, -0.1f);
}

TEST(Sh, WindowsReduceRingingAndKeepTheMean) {
  const auto none = windowFactors(Window::kNone, 3.0f);
  for (float f : none) EXPECT_EQ(f, 1.0f);
  const auto hann = windowFactors(Window::kHanning, 3.0f);
  EXPECT_FLOAT_EQ(hann[0], 1.0f);
  EXPECT_NEAR(hann[1], 0.75f, 1e-6f);
  EXPECT_NEAR(hann[2], 0.25f, 1e-6f);
  EXPECT_EQ(hann[3], 0.0f);
  const auto lanczos = windowFactors(Window::kLanczos, 3.0f);
  EXPECT_NEAR(lanczos[1], std::sin(kPi / 3) / (kPi / 3), 1e-6);
  EXPECT_NEAR(lanczos[2], std::sin(2 * kPi / 3) / (2 * kPi / 3), 1e-6);

  // A delta light reconstructed with 4 bands rings to about -0.3 of its peak; windows damp it.
  const glm::vec3 d = glm::normalize(glm::vec3(0.2f, 0.9f, -0.3f));
  auto minimum = [&](const Sh<4>& f) {
    float m = 1e30f;
    std::mt19937 rng(2);
    for (int k = 0; k < 5000; ++k) m = std::min(m, evaluate(f, randomUnit(rng)));
    return m;
  };
  Sh<4> raw;
  projectAdd(raw, d, 1.0f);
  Sh<4> hanned = raw, lanczosed = raw;
  scaleBands(hanned, windowFactors(Window::kHanning, 4.0f));
  scaleBands(lanczosed, windowFactors(Window::kLanczos, 4.0f));
  EXPECT_EQ(hanned.c[0], raw.c[0]);
  EXPECT_GT(minimum(hanned), 0.5f * minimum(raw));
  EXPECT_GT(minimum(lanczosed), 0.9f * minimum(raw));
  EXPECT_LT(minimum(raw), -0.05f);
}

TEST(Sh, RuntimeBandsMatchTemplates) {
  std::mt19937 rng(9);
  for (int k = 0; k < 100; ++k) {
    const glm::vec3 d = randomUnit(rng), n = randomUnit(rng);
    float y4[16], yr[16];
    evalBasis<4>(d, y4);
    for (int bands = 1; bands <= 4; ++bands) {
      evalBasis(bands, d, yr);
      for (int i = 0; i < bands * bands; ++i) EXPECT_EQ(yr[i], y4[i]);
    }
    Sh<3> t;
    float r[9] = {};
    projectAdd(t, d, 2.0f);
    projectAdd(3, d, 2.0f, r);
    for (int i = 0; i < 9; ++i) EXPECT_EQ(t.c[i], r[i]);
    EXPECT_NEAR(evaluate(t, n), evaluate(3, r, n), 1e-6f);
    EXPECT_NEAR(irradiance(t, n), irradiance(3, r, n), 1e-6f);
    ShRgb<3> rgb;
    projectAdd(rgb, d, glm::vec3(2.0f, 1.0f, 0.5f));
    EXPECT_NEAR(evaluate(rgb, n).x, evaluate(t, n), 1e-6f);
    EXPECT_NEAR(evaluate(rgb, n).z, 0.25f * evaluate(t, n), 1e-6f);
  }
}

}  // namespace
}  // namespace lightlink::sh
