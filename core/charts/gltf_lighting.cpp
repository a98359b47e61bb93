#include "core/charts/gltf_lighting.h"

#include <algorithm>
#include <map>
#include <set>

#include <tiny_gltf.h>

namespace lightlink::charts {
namespace {

tinygltf::Value toValue(const nlohmann::json& j) {
  switch (j.type()) {
    case nlohmann::json::value_t::object: {
      tinygltf::Value::Object o;
      for (const auto& [k, v] : j.items()) o[k] = toValue(v);
      return tinygltf::Value(std::move(o));
    }
    case nlohmann::json::value_t::array: {
      tinygltf::Value::Array a;
      for (const auto& v : j) a.push_back(toValue(v));
      return tinygltf::Value(std::move(a));
    }
    case nlohmann::json::value_t::string: return tinygltf::Value(j.get<std::string>());
    case nlohmann::json::value_t::boolean: return tinygltf::Value(j.get<bool>());
    case nlohmann::json::value_t::number_integer:
    case nlohmann::json::value_t::number_unsigned: return tinygltf::Value(j.get<int>());
    case nlohmann::json::value_t::number_float: return tinygltf::Value(j.get<double>());
    default: return tinygltf::Value();
  }
}

void use(tinygltf::Model& model, const char* extension) {
  if (std::find(model.extensionsUsed.begin(), model.extensionsUsed.end(), extension) == model.extensionsUsed.end())
    model.extensionsUsed.push_back(extension);
}

// The irradiance texture: linear filtering, clamped (texels past the chart edge are gutter),
// its image named through LIGHTLINK_texture_exr (see the header). One that is there already
// (the input was a lightmapped glTF) is reused.
std::pair<int, int> addIrradianceTexture(tinygltf::Model& model, const std::string& uri) {
  for (std::size_t t = 0; t < model.textures.size(); ++t) {
    const auto it = model.textures[t].extensions.find("LIGHTLINK_texture_exr");
    if (it == model.textures[t].extensions.end() || !it->second.Has("source")) continue;
    const int image = it->second.Get("source").GetNumberAsInt();
    if (image >= 0 && static_cast<std::size_t>(image) < model.images.size() &&
        model.images[static_cast<std::size_t>(image)].uri == uri)
      return {static_cast<int>(t), image};
  }
  const char* name = "lightlink irradiance (L0)";
  tinygltf::Image image;
  image.name = name;
  image.uri = uri;
  model.images.push_back(std::move(image));
  tinygltf::Sampler sampler;
  sampler.magFilter = TINYGLTF_TEXTURE_FILTER_LINEAR;
  sampler.minFilter = TINYGLTF_TEXTURE_FILTER_LINEAR;
  sampler.wrapS = TINYGLTF_TEXTURE_WRAP_CLAMP_TO_EDGE;
  sampler.wrapT = TINYGLTF_TEXTURE_WRAP_CLAMP_TO_EDGE;
  model.samplers.push_back(std::move(sampler));
  tinygltf::Texture texture;
  texture.name = name;
  texture.sampler = static_cast<int>(model.samplers.size() - 1);
  tinygltf::Value::Object exr;
  exr["source"] = tinygltf::Value(static_cast<int>(model.images.size() - 1));
  texture.extensions["LIGHTLINK_texture_exr"] = tinygltf::Value(std::move(exr));
  model.textures.push_back(std::move(texture));
  use(model, "LIGHTLINK_texture_exr");
  return {static_cast<int>(model.textures.size() - 1), static_cast<int>(model.images.size() - 1)};
}

}  // namespace

Expected<int> addGltfLighting(tinygltf::Model& model, const std::vector<std::pair<int, int>>& lightmapped,
                              const GltfLighting& lighting) {
  if (!lighting.description.is_null()) {
    if (!lighting.description.is_object())
      return invalidInput("glTF writer: the LIGHTLINK_lighting description must be a JSON object");
    model.extensions["LIGHTLINK_lighting"] = toValue(lighting.description);
    use(model, "LIGHTLINK_lighting");
  }
  if (lighting.irradiance_uri.empty() || lightmapped.empty()) return -1;

  const std::set<std::pair<int, int>> lit(lightmapped.begin(), lightmapped.end());
  std::set<int> shared;  // materials (-1: none) used by a primitive without the lightmap
  for (std::size_t m = 0; m < model.meshes.size(); ++m)
    for (std::size_t p = 0; p < model.meshes[m].primitives.size(); ++p)
      if (!lit.count({static_cast<int>(m), static_cast<int>(p)})) shared.insert(model.meshes[m].primitives[p].material);
  shared.insert(-1);  // no material: the lightmapped ones get a default material to carry the extension

  // Lightmapped primitives in file order, so copies get the same indices every run.
  std::map<int, int> copy_of;  // material (-1: none) -> material the lightmapped primitives use
  std::set<int> bound;
  for (const auto& [mesh, prim] : lit) {
    if (mesh < 0 || static_cast<std::size_t>(mesh) >= model.meshes.size() || prim < 0 ||
        static_cast<std::size_t>(prim) >= model.meshes[static_cast<std::size_t>(mesh)].primitives.size())
      return internalError("glTF writer: lightmapped primitive {} of mesh {} is not in the model", prim, mesh);
    int& material = model.meshes[static_cast<std::size_t>(mesh)].primitives[static_cast<std::size_t>(prim)].material;
    if (material >= static_cast<int>(model.materials.size()))
      return invalidInput("glTF writer: primitive {} of mesh {} names material {} of {}", prim, mesh, material,
                          model.materials.size());
    if (shared.count(material)) {
      auto [it, inserted] = copy_of.try_emplace(material, static_cast<int>(model.materials.size()));
      if (inserted) {
        tinygltf::Material copy;  // glTF's default material when there was none
        if (material >= 0) copy = model.materials[static_cast<std::size_t>(material)];
        copy.name = (material >= 0 ? copy.name + " " : std::string()) + "(lightmapped)";
        model.materials.push_back(std::move(copy));
      }
      material = it->second;
    }
    bound.insert(material);
  }
  const auto [texture, image] = addIrradianceTexture(model, lighting.irradiance_uri);
  for (const int material : bound) {
    tinygltf::Value::Object moz;
    moz["index"] = tinygltf::Value(texture);
    moz["texCoord"] = tinygltf::Value(lighting.lightmap_texcoord);
    moz["intensity"] = tinygltf::Value(1.0);
    model.materials[static_cast<std::size_t>(material)].extensions["MOZ_lightmap"] = tinygltf::Value(std::move(moz));
  }
  use(model, "MOZ_lightmap");
  return image;
}

}  // namespace lightlink::charts
