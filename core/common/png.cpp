#include "core/common/png.h"

#include <algorithm>
#include <cmath>

#include <png.h>

namespace lightlink {

Status writePngRgb8(const std::string& path, int width, int height, std::span<const std::uint8_t> rgb,
                    const char* what) {
  if (width <= 0 || height <= 0 || rgb.size() != static_cast<std::size_t>(width) * height * 3)
    return internalError("{}: {}x{} image with {} bytes", what, width, height, rgb.size());
  png_image image{};
  image.version = PNG_IMAGE_VERSION;
  image.width = static_cast<png_uint_32>(width);
  image.height = static_cast<png_uint_32>(height);
  image.format = PNG_FORMAT_RGB;
  if (!png_image_write_to_file(&image, path.c_str(), 0, rgb.data(), width * 3, nullptr)) {
    const std::string why = image.message;
    png_image_free(&image);
    return ioError("{}: cannot write '{}': {}", what, path, why);
  }
  return {};
}

std::uint8_t encodeSrgb8(float linear) {
  const float c = std::clamp(linear, 0.0f, 1.0f);
  const float s = c <= 0.0031308f ? 12.92f * c : 1.055f * std::pow(c, 1.0f / 2.4f) - 0.055f;
  return static_cast<std::uint8_t>(std::lround(s * 255.0f));
}

}  // namespace lightlink
