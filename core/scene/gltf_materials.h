// Internal to core/scene: glTF materials and textures into Scene::materials/textures.
//
// Images are decoded by tinygltf (stb) through `decodeImage`, installed as its image
// loader so that (a) an image stored in a bufferView is range-checked before a byte of
// it is read, (b) LoadOptions::load_textures=false skips decoding, and (c) an image that
// cannot be decoded becomes a warning (its texture samples as white) instead of failing
// the whole scene.
#pragma once

#include <string>
#include <vector>

#include "core/scene/gltf_context.h"

namespace lightlink::scene::gltf {

struct ImageDecodeState {
  const tinygltf::Model* model = nullptr;  // the model tinygltf is filling
  bool decode = true;
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

Status loadTextures(const Context& ctx);
Status loadMaterials(const Context& ctx);

}  // namespace lightlink::scene::gltf
