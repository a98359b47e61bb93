// PNG writing for the pictures people look at (chart layouts, irradiance previews, rendered
// frames): 8-bit RGB rows, top row first, through libpng's simplified API. `what` names the
// picture in the error message ("chart preview", "render", ...).
#pragma once

#include <cstdint>
#include <span>
#include <string>

#include "core/common/status.h"

namespace lightlink {

Status writePngRgb8(const std::string& path, int width, int height, std::span<const std::uint8_t> rgb,
                    const char* what);

// Linear [0, 1] -> sRGB-encoded 8-bit (values outside are clamped).
std::uint8_t encodeSrgb8(float linear);

}  // namespace lightlink
