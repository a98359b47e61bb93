// Decoding an image file's bytes into a scene Texture (RGBA8, row 0 = top), for importers
// that read image files themselves (OBJ/MTL and FBX through assimp). The LoadOptions image
// budgets are checked from the header before a byte is inflated, as the glTF path does;
// an image stb cannot decode is reported back for the caller to turn into a warning.
#pragma once

#include <cstdint>
#include <string>
#include <string_view>

#include "core/common/status.h"
#include "core/scene/scene.h"

namespace lightlink::scene {

struct ImageBudget {
  std::uint64_t max_image_pixels = 0;  // 0 = no limit (LoadOptions)
  std::uint64_t max_image_bytes = 0;
  std::uint64_t decoded_bytes = 0;     // what the images decoded so far take
};

// Fills out.width/height/rgba8 from `bytes`. Over a budget: kResourceExhausted naming
// `object`. Undecodable: Status::ok() with `problem` set and `out` left without pixels.
Status decodeImageRgba8(std::string_view bytes, std::string_view object, ImageBudget& budget, Texture& out,
                        std::string& problem);

}  // namespace lightlink::scene
