// glTF sampler wrap modes as the texture lookups apply them: one header-only copy for the
// material lookups (core/scene/texture.cpp) and the ray tracer's alpha test (core/rt/cutout,
// which uses scene types as headers only and does not link core/scene).
#pragma once

#include <cmath>

namespace lightlink::scene::wrap {

inline constexpr int kRepeat = 10497;
inline constexpr int kMirroredRepeat = 33648;  // anything else is CLAMP_TO_EDGE (33071)

// Folds a texture coordinate into the range the wrap mode maps onto [0, 1] before it is
// scaled to texels, so huge UVs cannot overflow the integer texel index.
inline float foldCoordinate(float u, int wrap) {
  if (!std::isfinite(u)) return 0.0f;
  if (wrap == kRepeat) return u - std::floor(u);
  if (wrap == kMirroredRepeat) return u - 2.0f * std::floor(0.5f * u);  // [0, 2)
  return std::fmin(std::fmax(u, -1.0f), 2.0f);
}

inline int wrapTexel(int i, int n, int wrap) {
  if (wrap == kRepeat) return ((i % n) + n) % n;
  if (wrap == kMirroredRepeat) {
    const int period = 2 * n;
    const int k = ((i % period) + period) % period;
    return k < n ? k : period - 1 - k;
  }
  return i < 0 ? 0 : (i >= n ? n - 1 : i);
}

}  // namespace lightlink::scene::wrap
