#include <array>
#include <cmath>

#include "core/scene/scene.h"
#include "core/scene/texture_wrap.h"

namespace lightlink::scene {
namespace {

using wrap::foldCoordinate;
using wrap::kMirroredRepeat;
using wrap::kRepeat;
using wrap::wrapTexel;

// sRGB EOTF (IEC 61966-2-1) for the 256 8-bit codes.
const std::array<float, 256>& srgbToLinearTable() {
  static const std::array<float, 256> table = [] {
    std::array<float, 256> t{};
    for (int i = 0; i < 256; ++i) {
      const double c = i / 255.0;
      t[static_cast<std::size_t>(i)] =
          static_cast<float>(c <= 0.04045 ? c / 12.92 : std::pow((c + 0.055) / 1.055, 2.4));
    }
    return t;
  }();
  return table;
}

}  // namespace

glm::vec4 Texture::sampleSrgb(glm::vec2 uv) const {
  // Not decoded (LoadOptions::load_textures = false, or an undecodable image): neutral
  // white, so the material's factors apply alone.
  if (width <= 0 || height <= 0 || (channels != 3 && channels != 4) ||
      rgba8.size() < static_cast<std::size_t>(width) * height * static_cast<std::size_t>(channels)) {
    return glm::vec4(1.0f);
  }
  const auto& lut = srgbToLinearTable();
  const auto stride = static_cast<std::size_t>(channels);
  const auto texel = [&](int x, int y) {
    const std::size_t at = (static_cast<std::size_t>(y) * static_cast<std::size_t>(width) +
                            static_cast<std::size_t>(x)) * stride;
    return glm::vec4(lut[rgba8[at]], lut[rgba8[at + 1]], lut[rgba8[at + 2]],
                     stride == 4 ? rgba8[at + 3] / 255.0f : 1.0f);
  };
  // Texel centres sit at (i + 0.5) / size, as in GL.
  const float x = foldCoordinate(uv.x, wrap_s) * static_cast<float>(width) - 0.5f;
  const float y = foldCoordinate(uv.y, wrap_t) * static_cast<float>(height) - 0.5f;
  if (nearest) {
    return texel(wrapTexel(static_cast<int>(std::floor(x + 0.5f)), width, wrap_s),
                 wrapTexel(static_cast<int>(std::floor(y + 0.5f)), height, wrap_t));
  }
  const float fx = std::floor(x), fy = std::floor(y);
  const float tx = x - fx, ty = y - fy;
  const int x0 = static_cast<int>(fx), y0 = static_cast<int>(fy);
  const int xa = wrapTexel(x0, width, wrap_s), xb = wrapTexel(x0 + 1, width, wrap_s);
  const int ya = wrapTexel(y0, height, wrap_t), yb = wrapTexel(y0 + 1, height, wrap_t);
  // Filter in linear space: decoding after averaging would darken edges.
  const glm::vec4 top = glm::mix(texel(xa, ya), texel(xb, ya), tx);
  const glm::vec4 bottom = glm::mix(texel(xa, yb), texel(xb, yb), tx);
  return glm::mix(top, bottom, ty);
}

}  // namespace lightlink::scene
