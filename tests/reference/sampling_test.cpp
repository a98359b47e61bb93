// The reference's samplers against their own pdfs (chi-square over equal-probability bins)
// and its random stream's independence from the point and sample it is seeded for.
#include "core/reference/path_sampling.h"

#include <array>
#include <cmath>
#include <numbers>
#include <vector>

#include <gtest/gtest.h>

namespace lightlink::reference {
namespace {

constexpr float kPi = std::numbers::pi_v<float>;

double chiSquare(const std::vector<int>& counts, double expected) {
  double chi2 = 0.0;
  for (int c : counts) chi2 += (c - expected) * (c - expected) / expected;
  return chi2;
}

// Cosine-weighted directions: 1 - z^2 = sin^2(theta) and phi / 2pi are each uniform and
// independent under pdf cos(theta) / pi, so an 8 x 8 grid over them has equal-probability bins.
TEST(ReferenceSampling, CosineHemisphereMatchesItsPdf) {
  constexpr int kBins = 8, kSamples = 64000;
  std::vector<int> counts(kBins * kBins, 0);
  SampleRng rng(7, 0, 0);
  for (int i = 0; i < kSamples; ++i) {
    const glm::vec3 d = cosineHemisphere(rng.next(), rng.next());
    ASSERT_NEAR(glm::length(d), 1.0f, 1e-5f);
    ASSERT_GE(d.z, 0.0f);
    const float s = 1.0f - d.z * d.z;
    float phi = std::atan2(d.y, d.x);
    if (phi < 0.0f) phi += 2.0f * kPi;
    const int a = std::min(kBins - 1, int(s * kBins));
    const int b = std::min(kBins - 1, int(phi / (2.0f * kPi) * kBins));
    ++counts[std::size_t(a * kBins + b)];
  }
  // 63 degrees of freedom: P(chi2 > 103.4) = 0.001 for a correct sampler.
  const double chi2 = chiSquare(counts, double(kSamples) / (kBins * kBins));
  EXPECT_LT(chi2, 103.4) << "cosine hemisphere sampler does not follow cos/pi";
  EXPECT_FLOAT_EQ(cosineHemispherePdf(1.0f), 1.0f / kPi);
  EXPECT_EQ(cosineHemispherePdf(-0.5f), 0.0f);
}

// Uniform triangle points: the 16 triangles of a twice-subdivided triangle have equal area.
// A point with barycentrics (b1, b2) lies in cell (floor(4 b1), floor(4 b2)), in its lower or
// upper half by whether the fractional parts sum past 1.
TEST(ReferenceSampling, UniformTriangleMatchesItsPdf) {
  constexpr int kSamples = 48000;
  std::vector<int> counts(32, 0);
  SampleRng rng(11, 3, 0);
  for (int i = 0; i < kSamples; ++i) {
    const glm::vec2 b = uniformTriangle(rng.next(), rng.next());
    ASSERT_GE(b.x, 0.0f);
    ASSERT_GE(b.y, 0.0f);
    ASSERT_LE(b.x + b.y, 1.0f + 1e-6f);
    const float x = 4.0f * b.x, y = 4.0f * b.y;
    const int ix = std::min(3, int(x)), iy = std::min(3, int(y));
    const bool upper = (x - float(ix)) + (y - float(iy)) >= 1.0f;
    ++counts[std::size_t((ix * 4 + iy) * 2 + (upper ? 1 : 0))];
  }
  std::vector<int> used;
  for (int ix = 0; ix < 4; ++ix)
    for (int iy = 0; iy < 4; ++iy) {
      if (ix + iy <= 3) used.push_back(counts[std::size_t((ix * 4 + iy) * 2)]);
      if (ix + iy <= 2) used.push_back(counts[std::size_t((ix * 4 + iy) * 2 + 1)]);
      if (ix + iy > 3) {
        EXPECT_EQ(counts[std::size_t((ix * 4 + iy) * 2)], 0);
      }
    }
  ASSERT_EQ(used.size(), 16u);
  // 15 degrees of freedom: P(chi2 > 37.7) = 0.001.
  EXPECT_LT(chiSquare(used, kSamples / 16.0), 37.7);
}

TEST(ReferenceSampling, StreamsDependOnSeedPointAndSample) {
  const auto first = [](std::uint64_t seed, std::uint64_t point, std::uint64_t sample) {
    SampleRng rng(seed, point, sample);
    return rng.next();
  };
  EXPECT_EQ(first(1, 2, 3), first(1, 2, 3));
  EXPECT_NE(first(1, 2, 3), first(2, 2, 3));
  EXPECT_NE(first(1, 2, 3), first(1, 3, 3));
  EXPECT_NE(first(1, 2, 3), first(1, 2, 4));
  // Neighbouring streams are uncorrelated: the mean of products of paired draws is 1/4.
  double sum = 0.0;
  constexpr int kPairs = 20000;
  for (int i = 0; i < kPairs; ++i) sum += double(first(5, 0, std::uint64_t(i))) * first(5, 0, std::uint64_t(i) + 1);
  EXPECT_NEAR(sum / kPairs, 0.25, 0.01);
}

TEST(ReferenceSampling, PowerHeuristicWeightsSumToOne) {
  EXPECT_FLOAT_EQ(powerHeuristic(2.0f, 1.0f) + powerHeuristic(1.0f, 2.0f), 1.0f);
  EXPECT_FLOAT_EQ(powerHeuristic(3.0f, 0.0f), 1.0f);
  EXPECT_EQ(powerHeuristic(0.0f, 0.0f), 0.0f);
}

}  // namespace
}  // namespace lightlink::reference
