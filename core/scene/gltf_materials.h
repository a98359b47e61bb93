// Internal to core/scene: glTF materials and textures into Scene::materials/textures.
//
// Images are decoded (stb, straight to RGB8, or RGBA8 where the alpha mode reads alpha)
// through `decodeImage`, installed as tinygltf's
// image loader so that (a) an image stored in a bufferView is range-checked before a byte of
// it is read, (b) only the images that feed lighting (lighting_images.h) are decoded, each
// once however many textures share it, and none with LoadOptions::load_textures=false, and
// (c) an image that cannot be decoded becomes a warning (its texture samples as white, so
// the material's factor applies alone) instead of failing the whole scene.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "core/scene/gltf_context.h"

namespace lightlink::scene::gltf {

struct ImageDecodeState {
  const tinygltf::Model* model = nullptr;  // the model tinygltf is filling
  bool decode = true;
  std::vector<bool> wanted;                // per image: feeds lighting (lighting_images.h)
  std::vector<bool> alpha;                 // per image: keep alpha (RGBA8), else RGB8
  // Per image: RGBA8 or RGB8 pixels (channels[i] bytes each), row 0 = top, kept here (not
  // in tinygltf::Image) so that loadTextures can move them into the Scene without a copy.
  std::vector<std::vector<std::uint8_t>> pixels;
  std::vector<int> channels;
  std::size_t decoded = 0;                 // images decoded
  std::vector<std::string> problems;       // "image N: ..." per image not decoded
  std::string fatal;                       // set when a bufferView image is out of range
  std::string over_budget;                 // set when an image is over a LoadOptions limit
  std::uint64_t max_image_pixels = 0;      // LoadOptions limits (0 = none)
  std::uint64_t max_image_bytes = 0;
  std::uint64_t decoded_bytes = 0;         // what the images decoded so far take
};

// tinygltf::LoadImageDataFunction; user_data is an ImageDecodeState.
bool decodeImage(tinygltf::Image* image, int image_index, std::string* err, std::string* warn,
                 int req_width, int req_height, const unsigned char* bytes, int size,
                 void* user_data);

// Scene::textures from the model; the pixels of the images in `images` are moved into them
// (copied where several textures share an image). Warns for a texture that feeds lighting
// but whose image was not decoded.
Status loadTextures(const Context& ctx, ImageDecodeState& images);
Status loadMaterials(const Context& ctx);

}  // namespace lightlink::scene::gltf
