#include "core/scene/image_decode.h"

#include <limits>

#include <stb/stb_image.h>

namespace lightlink::scene {

Status decodeImageRgba8(std::string_view bytes, std::string_view object, ImageBudget& budget, Texture& out,
                        std::string& problem) {
  problem.clear();
  if (bytes.empty() || bytes.size() > std::size_t(std::numeric_limits<int>::max())) {
    problem = bytes.empty() ? "the file is empty" : "the file is too large to decode";
    return Status::ok();
  }
  const auto* data = reinterpret_cast<const stbi_uc*>(bytes.data());
  const int size = static_cast<int>(bytes.size());
  int w = 0, h = 0, channels = 0;
  if (!stbi_info_from_memory(data, size, &w, &h, &channels) || w <= 0 || h <= 0) {
    const char* why = stbi_failure_reason();
    problem = fmt::format("cannot be decoded ({})", why ? why : "unknown image format");
    return Status::ok();
  }
  // stb decodes to RGBA8 here (no 16-bit intermediate), and the texture keeps that buffer.
  const std::uint64_t pixels = std::uint64_t(w) * std::uint64_t(h);
  const std::uint64_t cost = pixels * 4;
  if (budget.max_image_pixels != 0 && pixels > budget.max_image_pixels)
    return resourceExhausted("{}: {}x{} = {} pixels is above the limit of {} pixels per image (max_image_pixels)",
                             object, w, h, pixels, budget.max_image_pixels);
  if (budget.max_image_bytes != 0 && budget.decoded_bytes + cost > budget.max_image_bytes)
    return resourceExhausted("{}: decoding it ({}x{}) brings the decoded images to {} MiB, above the limit of {} MiB "
                             "(max_image_bytes)",
                             object, w, h, (budget.decoded_bytes + cost) >> 20, budget.max_image_bytes >> 20);
  stbi_uc* pixels_rgba = stbi_load_from_memory(data, size, &w, &h, &channels, 4);
  if (!pixels_rgba) {
    const char* why = stbi_failure_reason();
    problem = fmt::format("cannot be decoded ({})", why ? why : "unknown reason");
    return Status::ok();
  }
  budget.decoded_bytes += cost;
  out.width = w;
  out.height = h;
  out.rgba8.assign(pixels_rgba, pixels_rgba + cost);
  stbi_image_free(pixels_rgba);
  return Status::ok();
}

}  // namespace lightlink::scene
