// The random numbers and direction/area samplers of the reference path tracer.
//
// Every sample of the reference draws from its own counter-based stream, seeded from
// (seed, point index, sample index) alone, so a point's estimate never depends on which
// thread ran it or on which other points were in the query. The samplers are pure
// functions of their uniform inputs; tests/reference checks each against its pdf with a
// chi-square test.
#pragma once

#include <cmath>
#include <cstdint>
#include <numbers>

#include <glm/glm.hpp>

#include "core/common/sampling.h"

namespace lightlink::reference {

// SplitMix64 stream: one 64-bit state advanced by the golden-ratio increment and finalised by
// mixBits. Statistically independent enough for Monte Carlo (it passes BigCrush) and cheap to
// seed per sample, which is what keeps results identical for any thread count.
class SampleRng {
 public:
  SampleRng(std::uint64_t seed, std::uint64_t point, std::uint64_t sample)
      : state_(mixBits(mixBits(mixBits(seed ^ 0x243f6a8885a308d3ULL) ^ (point * 0xd1b54a32d192ed03ULL)) ^
                       (sample * 0x9e3779b97f4a7c15ULL))) {}
  // Uniform in [0, 1) with 24 bits (floats cannot hold more below 1).
  float next() {
    state_ += 0x9e3779b97f4a7c15ULL;
    return unitFloat(mixBits(state_));
  }

 private:
  std::uint64_t state_;
};

// Cosine-weighted direction on the +z hemisphere from (u1, u2) in [0,1)^2, pdf = z / pi per
// steradian. Concentric (Shirley-Chiu) disk mapping then lifted to the hemisphere (Malley),
// which keeps strata compact and has no singular point at the pole.
inline glm::vec3 cosineHemisphere(float u1, float u2) {
  constexpr float kPiOver4 = std::numbers::pi_v<float> / 4.0f;
  const float a = 2.0f * u1 - 1.0f, b = 2.0f * u2 - 1.0f;
  float r = 0.0f, phi = 0.0f;
  if (a != 0.0f || b != 0.0f) {
    if (std::abs(a) > std::abs(b)) {
      r = a;
      phi = kPiOver4 * (b / a);
    } else {
      r = b;
      phi = 2.0f * kPiOver4 - kPiOver4 * (a / b);
    }
  }
  const float x = r * std::cos(phi), y = r * std::sin(phi);
  return {x, y, std::sqrt(std::max(0.0f, 1.0f - x * x - y * y))};
}

inline float cosineHemispherePdf(float cos_theta) {
  return cos_theta > 0.0f ? cos_theta * std::numbers::inv_pi_v<float> : 0.0f;
}

// Uniform point on a triangle from (u1, u2) in [0,1)^2 as Embree barycentrics (u, v), with
// p = (1 - u - v) p0 + u p1 + v p2; pdf = 1 / area.
inline glm::vec2 uniformTriangle(float u1, float u2) {
  const float su = std::sqrt(u1);
  return {su * (1.0f - u2), su * u2};
}

// Power heuristic (beta = 2) weight of a strategy with pdf `a` against one with pdf `b`
// (Veach 1997): both pdfs in the same measure (here per steradian).
inline float powerHeuristic(float a, float b) {
  const float a2 = a * a, b2 = b * b;
  return a2 + b2 > 0.0f ? a2 / (a2 + b2) : 0.0f;
}

}  // namespace lightlink::reference
