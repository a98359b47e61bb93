// Internal to core/scene: glTF materials and textures into Scene::materials/textures.
//
// Images go through `queueImage`, installed as tinygltf's image loader, so that (a) an
// image stored in a bufferView is range-checked before a byte of it is read, (b) only the
// images that feed lighting (lighting_images.h) are decoded, each once however many textures
// share it, and none with LoadOptions::load_textures=false, with the budgets checked from
// their headers first; then `decodeQueuedImages` decodes them, several at once (stb, straight
// to RGB8, or RGBA8 where the alpha mode reads alpha), and (c) an image that cannot be decoded
// becomes a warning (its texture samples as white, so the material's factor applies alone)
// instead of failing the whole scene.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "core/scene/gltf_context.h"

namespace lightlink::scene::gltf {

// One image lighting reads: its encoded bytes, queued by queueImage after the budget check,
// then its pixels, decoded by decodeQueuedImages.
struct QueuedImage {
  std::string object;                 // "image N 'name'", for messages
  std::vector<unsigned char> encoded;
  int keep_channels = 3;              // 4 where alpha matters (lighting_images.h)
  // RGB8 or RGBA8 (channels bytes a pixel), row 0 = top, as stb allocated it: loadTextures
  // copies it into the Scene and frees it at once, so at most one image exists twice
  // (decoding straight into the Scene would need stb to allocate as std::vector does).
  std::unique_ptr<unsigned char, void (*)(void*)> pixels{nullptr, &freePixels};
  int width = 0, height = 0, channels = 0;
  std::size_t bytes() const { return std::size_t(width) * std::size_t(height) * std::size_t(channels); }
  static void freePixels(void* p);
};

struct ImageDecodeState {
  const tinygltf::Model* model = nullptr;  // the model tinygltf is filling
  bool decode = true;
  std::vector<bool> wanted;                // per image: feeds lighting (lighting_images.h)
  std::vector<bool> alpha;                 // per image: keep alpha (RGBA8), else RGB8
  std::vector<QueuedImage> queue;          // per image (empty for those not decoded)
  std::size_t decoded = 0;                 // images decoded
  std::vector<std::string> problems;       // "image N: ..." per image not decoded
  std::string fatal;                       // set when a bufferView image is out of range
  std::string over_budget;                 // set when an image is over a LoadOptions limit
  std::uint64_t max_image_pixels = 0;      // LoadOptions limits (0 = none)
  std::uint64_t max_image_bytes = 0;
  std::uint64_t budgeted_bytes = 0;        // what the queued images will take (from headers)
  std::uint64_t decoded_bytes = 0;         // what the decoded images take
};

// tinygltf::LoadImageDataFunction; user_data is an ImageDecodeState. Checks the budgets from
// the image header and queues the image; nothing is decoded here (tinygltf calls it for one
// image after another).
bool queueImage(tinygltf::Image* image, int image_index, std::string* err, std::string* warn,
                 int req_width, int req_height, const unsigned char* bytes, int size,
                 void* user_data);

// Decodes the queued images, several at once (JPEG/PNG decoding is most of a textured
// scene's load time); an image that cannot be decoded becomes a problem, in image order.
void decodeQueuedImages(ImageDecodeState& state);

// Scene::textures from the model; the pixels of the images in `images` are moved into them
// (copied where several textures share an image). Warns for a texture that feeds lighting
// but whose image was not decoded.
Status loadTextures(const Context& ctx, ImageDecodeState& images);
Status loadMaterials(const Context& ctx);

}  // namespace lightlink::scene::gltf
