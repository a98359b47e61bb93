// Which of a glTF's images feed lighting. lightlink's light transport reads only the diffuse
// albedo (baseColorTexture) and the emission (emissiveTexture, where emissiveFactor and
// KHR_materials_emissive_strength make the material emit) of the materials the meshes use;
// normal, metallic-roughness and occlusion maps, and images no such texture names, change
// nothing it computes. The loader decodes only these images and the artifact cache key
// hashes only these images' files, so both follow one rule.
//
// Computed from the glTF JSON alone (before tinygltf reads a file): entries of the wrong type
// or out of range are skipped here; the loader names them.
#pragma once

#include <vector>

#include <nlohmann/json_fwd.hpp>

namespace lightlink::scene {

struct LightingImages {
  std::vector<bool> images;    // per images[i]: decoded for lighting
  // Per images[i]: its alpha is kept too, as the base colour of an alphaMode MASK or BLEND
  // material (where alpha means coverage); every other image is decoded as RGB.
  std::vector<bool> alpha;
  std::vector<bool> textures;  // per textures[i]: sampled for lighting

  bool image(int i) const { return i >= 0 && static_cast<std::size_t>(i) < images.size() && images[i]; }
  bool texture(int i) const { return i >= 0 && static_cast<std::size_t>(i) < textures.size() && textures[i]; }
};

LightingImages lightingImages(const nlohmann::json& gltf);

}  // namespace lightlink::scene
