#include "core/scene/lighting_images.h"

#include <algorithm>

#include <nlohmann/json.hpp>

namespace lightlink::scene {
namespace {

const nlohmann::json* arrayOf(const nlohmann::json& j, const char* name) {
  const auto it = j.find(name);
  return it != j.end() && it->is_array() ? &*it : nullptr;
}

// The texture index of a textureInfo, -1 when absent or malformed; texCoord above 1 is
// ignored by the loader (it warns), so such a texture is not sampled either.
int textureIndex(const nlohmann::json& material, const char* parent, const char* field) {
  const nlohmann::json* holder = &material;
  if (parent != nullptr) {
    const auto p = material.find(parent);
    if (p == material.end() || !p->is_object()) return -1;
    holder = &*p;
  }
  const auto info = holder->find(field);
  if (info == holder->end() || !info->is_object()) return -1;
  const auto index = info->find("index");
  if (index == info->end() || !index->is_number_integer()) return -1;
  const auto coord = info->find("texCoord");
  if (coord != info->end() && (!coord->is_number_integer() || coord->get<long long>() < 0 ||
                               coord->get<long long>() > 1))
    return -1;
  return static_cast<int>(std::clamp<long long>(index->get<long long>(), -1, 1 << 30));
}

// As Material::isEmissive: a zero emissiveFactor (the glTF default) or a zero strength
// makes the emissive texture irrelevant.
bool emits(const nlohmann::json& material) {
  const auto factor = material.find("emissiveFactor");
  if (factor == material.end() || !factor->is_array()) return false;
  bool any = false;
  for (const nlohmann::json& v : *factor) any = any || (v.is_number() && v.get<double>() > 0.0);
  if (!any) return false;
  const auto ext = material.find("extensions");
  if (ext != material.end() && ext->is_object()) {
    const auto strength = ext->find("KHR_materials_emissive_strength");
    if (strength != ext->end() && strength->is_object()) {
      const auto v = strength->find("emissiveStrength");
      if (v != strength->end() && v->is_number() && !(v->get<double>() > 0.0)) return false;
    }
  }
  return true;
}

}  // namespace

LightingImages lightingImages(const nlohmann::json& gltf) {
  LightingImages out;
  if (!gltf.is_object()) return out;
  const nlohmann::json* images = arrayOf(gltf, "images");
  const nlohmann::json* textures = arrayOf(gltf, "textures");
  const nlohmann::json* materials = arrayOf(gltf, "materials");
  const nlohmann::json* meshes = arrayOf(gltf, "meshes");
  out.images.assign(images ? images->size() : 0, false);
  out.alpha.assign(out.images.size(), false);
  out.textures.assign(textures ? textures->size() : 0, false);
  if (materials == nullptr || meshes == nullptr || textures == nullptr) return out;

  // Materials some primitive uses: an asset library's unused materials cost nothing.
  std::vector<bool> used(materials->size(), false);
  for (const nlohmann::json& mesh : *meshes) {
    if (!mesh.is_object()) continue;
    const nlohmann::json* primitives = arrayOf(mesh, "primitives");
    if (primitives == nullptr) continue;
    for (const nlohmann::json& prim : *primitives) {
      if (!prim.is_object()) continue;
      const auto m = prim.find("material");
      if (m == prim.end() || !m->is_number_integer()) continue;
      const long long i = m->get<long long>();
      if (i >= 0 && static_cast<std::size_t>(i) < used.size()) used[static_cast<std::size_t>(i)] = true;
    }
  }
  auto take = [&](int texture, bool alpha) {
    if (texture < 0 || static_cast<std::size_t>(texture) >= textures->size()) return;
    out.textures[static_cast<std::size_t>(texture)] = true;
    const nlohmann::json& t = (*textures)[static_cast<std::size_t>(texture)];
    if (!t.is_object()) return;
    const auto source = t.find("source");
    if (source == t.end() || !source->is_number_integer()) return;
    const long long image = source->get<long long>();
    if (image >= 0 && static_cast<std::size_t>(image) < out.images.size()) {
      out.images[static_cast<std::size_t>(image)] = true;
      if (alpha) out.alpha[static_cast<std::size_t>(image)] = true;
    }
  };
  for (std::size_t m = 0; m < materials->size(); ++m) {
    const nlohmann::json& material = (*materials)[m];
    if (!used[m] || !material.is_object()) continue;
    const auto mode = material.find("alphaMode");
    const bool coverage = mode != material.end() && mode->is_string() &&
                          (mode->get_ref<const std::string&>() == "MASK" || mode->get_ref<const std::string&>() == "BLEND");
    take(textureIndex(material, "pbrMetallicRoughness", "baseColorTexture"), coverage);
    if (emits(material)) take(textureIndex(material, nullptr, "emissiveTexture"), false);
  }
  return out;
}

}  // namespace lightlink::scene
