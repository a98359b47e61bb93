// The array conversion to half (F16C where the CPU has it) against the scalar Imath one:
// bit-identical values and the same clamped count, on the values where conversions differ
// if anything is wrong: rounding ties, subnormals, the half range's edge, NaN, infinity.
#include <gtest/gtest.h>

#include <bit>
#include <cstring>
#include <limits>
#include <random>
#include <vector>

#include "core/common/half.h"

namespace lightlink {
namespace {

TEST(HalfArray, MatchesTheScalarConversionBitForBit) {
  std::vector<float> v = {0.0f, -0.0f, 1.0f, -2.0f, kHalfMax, -kHalfMax, 65519.0f, 65520.0f, -70000.0f, 1e30f,
                          std::numeric_limits<float>::infinity(), -std::numeric_limits<float>::infinity(),
                          std::numeric_limits<float>::quiet_NaN(), std::numeric_limits<float>::signaling_NaN(),
                          5.96e-8f, 2.98e-8f, 2.99e-8f, 6.1e-5f, 6.09e-5f, std::numeric_limits<float>::denorm_min()};
  // Exact ties between two halves: 1 + (2k + 1) 2^-11 lies half-way between halves 2^-10 apart.
  for (int k = 0; k < 64; ++k) v.push_back(1.0f + float(2 * k + 1) * 0x1.0p-11f);
  // Every half value and the floats right next to each one, then random bit patterns.
  for (std::uint32_t h = 0; h < 0x10000; ++h) {
    const float f = fromHalf(static_cast<half_bits>(h));
    v.push_back(f);
    v.push_back(std::nextafter(f, std::numeric_limits<float>::infinity()));
    v.push_back(std::nextafter(f, -std::numeric_limits<float>::infinity()));
  }
  std::mt19937 rng(11);
  for (int i = 0; i < 200000; ++i) v.push_back(std::bit_cast<float>(static_cast<std::uint32_t>(rng())));
  v.push_back(std::numeric_limits<float>::quiet_NaN());  // a NaN in the scalar tail too

  std::vector<half_bits> fast(v.size());
  const std::size_t clamped = toHalfSaturating(std::span<const float>(v), fast.data());
  std::size_t expected_clamped = 0;
  for (std::size_t i = 0; i < v.size(); ++i) {
    bool c = false;
    const half_bits want = toHalfSaturating(v[i], c);
    expected_clamped += c ? 1 : 0;
    ASSERT_EQ(fast[i], want) << "value " << i << " = " << v[i];
  }
  EXPECT_EQ(clamped, expected_clamped);
  EXPECT_GT(clamped, 1000u);  // the random patterns include many values beyond the range
}

}  // namespace
}  // namespace lightlink
