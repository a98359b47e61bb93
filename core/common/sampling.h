// Deterministic sample patterns shared by precompute stages: stratified directions on
// the sphere and hemisphere, the radical inverse (Halton), and an orthonormal frame around
// a normal. Everything here is a pure function of its arguments (no global RNG state), so
// results never depend on thread scheduling.
#pragma once

#include <cmath>
#include <cstdint>
#include <numbers>

#include <glm/glm.hpp>

namespace lightlink {

// Radical inverse of `index` in base `base` (Halton component), in [0, 1).
inline double radicalInverse(std::uint64_t index, std::uint32_t base) {
  const double inv_base = 1.0 / base;
  double inv = inv_base, result = 0.0;
  while (index > 0) {
    result += static_cast<double>(index % base) * inv;
    index /= base;
    inv *= inv_base;
  }
  return result;
}

// A 64-bit mix (SplitMix64 finaliser) for seeding per-item jitter reproducibly.
inline std::uint64_t mixBits(std::uint64_t v) {
  v ^= v >> 30;
  v *= 0xbf58476d1ce4e5b9ULL;
  v ^= v >> 27;
  v *= 0x94d049bb133111ebULL;
  v ^= v >> 31;
  return v;
}
inline float unitFloat(std::uint64_t bits) { return static_cast<float>(bits >> 40) * 0x1.0p-24f; }

// A 32-bit mix (Wellons' "lowbias32"; bias 0.17 in his hash-prospector measurements) for
// per-sample jitter in vectorised loops: 32-bit multiplies run 8 wide with AVX2, where
// mixBits's 64-bit ones stay scalar.
inline std::uint32_t mixBits32(std::uint32_t x) {
  x ^= x >> 16;
  x *= 0x7feb352dU;
  x ^= x >> 15;
  x *= 0x846ca68bU;
  x ^= x >> 16;
  return x;
}
// The top 24 bits as a float in [0, 1) (via int32, which vectorises; the same value).
inline float unitFloat32(std::uint32_t bits) {
  return static_cast<float>(static_cast<std::int32_t>(bits >> 8)) * 0x1.0p-24f;
}

// Orthonormal basis with n as +z (Duff et al. 2017, branchless and robust at n.z = -1).
inline void orthonormalBasis(const glm::vec3& n, glm::vec3& t, glm::vec3& b) {
  const float sign = std::copysign(1.0f, n.z);
  const float a = -1.0f / (sign + n.z);
  const float c = n.x * n.y * a;
  t = glm::vec3(1.0f + sign * n.x * n.x * a, sign * c, -sign * n.x);
  b = glm::vec3(c, sign + n.y * n.y * a, -n.y);
}

// Uniform direction on the unit sphere from (u1, u2) in [0,1)^2 (equal-area mapping).
inline glm::vec3 uniformSphere(float u1, float u2) {
  const float z = 1.0f - 2.0f * u1;
  const float r = std::sqrt(std::max(0.0f, 1.0f - z * z));
  const float phi = 2.0f * std::numbers::pi_v<float> * u2;
  return {r * std::cos(phi), r * std::sin(phi), z};
}

// Uniform direction on the +z hemisphere (equal-area mapping).
inline glm::vec3 uniformHemisphere(float u1, float u2) {
  const float z = 1.0f - u1;
  const float r = std::sqrt(std::max(0.0f, 1.0f - z * z));
  const float phi = 2.0f * std::numbers::pi_v<float> * u2;
  return {r * std::cos(phi), r * std::sin(phi), z};
}

// The two jitters in [0, 1) of sample `i` of a stratified grid, from 32-bit hashing
// (mixBits32): what the link rays' base pattern uses (links::LinkRays), x for the polar
// stratum and y for the azimuthal one.
inline glm::vec2 stratifiedJitter32(std::uint32_t i, std::uint32_t seed) {
  const std::uint32_t bits = mixBits32(seed ^ (i * 0x9e3779b9U));
  return {unitFloat32(bits), unitFloat32(mixBits32(bits))};
}

// Sample `i` of an n x n stratified grid with jitter from `seed`: stratum (i / n, i % n),
// so any n*n consecutive indices cover every stratum once.
inline glm::vec2 stratifiedSample(std::uint32_t i, std::uint32_t n, std::uint64_t seed) {
  const std::uint32_t sx = i % n, sy = (i / n) % n;
  const std::uint64_t bits = mixBits(seed ^ (std::uint64_t(i) * 0x9e3779b97f4a7c15ULL));
  const float jx = unitFloat(bits), jy = unitFloat(mixBits(bits));
  return {(static_cast<float>(sx) + jx) / static_cast<float>(n),
          (static_cast<float>(sy) + jy) / static_cast<float>(n)};
}

}  // namespace lightlink
