// IEEE 754 binary16 storage for the big arrays (link coefficients, lightmaps): half the
// bytes of float, which is what the bandwidth-bound cache lighting is paid in (seed 000
// sec 4.7). Conversion uses Imath's (OpenEXR's) tables and rounding, so what we store is
// bit-identical to what an EXR writer would store. Values beyond the half range are
// clamped, not turned into infinity, and the caller learns that it happened.
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <span>

#include <Imath/half.h>

namespace lightlink {

using half_bits = std::uint16_t;

inline constexpr float kHalfMax = 65504.0f;

inline half_bits toHalf(float v) { return imath_float_to_half(v); }
inline float fromHalf(half_bits h) { return imath_half_to_float(h); }

// Clamps |v| to kHalfMax before converting; sets `clamped` when it had to.
inline half_bits toHalfSaturating(float v, bool& clamped) {
  if (std::abs(v) > kHalfMax) {
    clamped = true;
    v = std::copysign(kHalfMax, v);
  }
  return imath_float_to_half(v);
}

// toHalfSaturating over an array, bit-identical to the scalar call per value; returns how
// many values were clamped. On x86-64 with F16C it converts 8 values per instruction (the
// daemon encodes ~0.5 M values per result on the path between relight and clients).
std::size_t toHalfSaturating(std::span<const float> src, half_bits* dst);

}  // namespace lightlink
