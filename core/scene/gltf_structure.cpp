#include "core/scene/gltf_structure.h"

#include <algorithm>
#include <array>

namespace lightlink::scene::gltf {
namespace {

constexpr std::array<std::string_view, 2> kSupported = {
    "KHR_lights_punctual",
    "KHR_materials_emissive_strength",
};

// Optional extensions whose effect a diffuse, opaque light transport cannot represent:
// the file loads, the effect is ignored, and the user is told what was approximated.
struct Approximated {
  std::string_view name;
  std::string_view consequence;
};
constexpr std::array<Approximated, 14> kApproximated = {{
    {"KHR_materials_transmission", "transmissive materials are treated as opaque"},
    {"KHR_materials_volume", "volumes are treated as opaque surfaces"},
    {"KHR_materials_ior", "index of refraction is ignored"},
    {"KHR_materials_specular", "specular layer is ignored (diffuse transport)"},
    {"KHR_materials_clearcoat", "clearcoat is ignored"},
    {"KHR_materials_sheen", "sheen is ignored"},
    {"KHR_materials_iridescence", "iridescence is ignored"},
    {"KHR_materials_anisotropy", "anisotropy is ignored"},
    {"KHR_materials_dispersion", "dispersion is ignored"},
    {"KHR_materials_unlit", "unlit materials are lit like any other"},
    {"KHR_materials_variants", "only the default material of each primitive is used"},
    {"KHR_materials_pbrSpecularGlossiness", "specular-glossiness materials use their default base colour"},
    {"KHR_texture_transform", "texture transforms are ignored (UVs used as stored)"},
    {"KHR_materials_diffuse_transmission", "diffuse transmission is ignored"},
}};

// Pointers to baked lighting that lightlink itself writes (docs/outputs.md, "The glTF and
// its lighting"): a bake recomputes what they point at, so loading ignores them silently.
constexpr std::array<std::string_view, 3> kBakeOutputs = {"MOZ_lightmap", "LIGHTLINK_lighting", "LIGHTLINK_texture_exr"};

}  // namespace

bool isSupportedExtension(std::string_view name) {
  for (std::string_view s : kSupported) {
    if (s == name) return true;
  }
  return false;
}

Status validateExtensions(const Context& ctx) {
  for (const std::string& name : ctx.model.extensionsRequired) {
    if (!isSupportedExtension(name)) {
      return ctx.unsupported("extensionsRequired",
                             fmt::format("required extension {} is not supported by lightlink "
                                         "(supported: KHR_lights_punctual, "
                                         "KHR_materials_emissive_strength)",
                                         name));
    }
  }
  for (const std::string& name : ctx.model.extensionsUsed) {
    if (isSupportedExtension(name)) continue;
    if (std::find(kBakeOutputs.begin(), kBakeOutputs.end(), name) != kBakeOutputs.end()) continue;
    bool known = false;
    for (const Approximated& a : kApproximated) {
      if (a.name == name) {
        ctx.warn("extensionsUsed", fmt::format("{}: {}", name, a.consequence));
        known = true;
      }
    }
    if (!known) ctx.warn("extensionsUsed", fmt::format("unknown extension {} is ignored", name));
  }
  return Status::ok();
}

Status validateBufferViews(const Context& ctx) {
  const tinygltf::Model& model = ctx.model;
  for (std::size_t i = 0; i < model.bufferViews.size(); ++i) {
    const tinygltf::BufferView& bv = model.bufferViews[i];
    const std::string object = describe("bufferView", static_cast<int>(i), bv.name);
    if (bv.buffer < 0 || static_cast<std::size_t>(bv.buffer) >= model.buffers.size()) {
      return ctx.invalid(object, fmt::format("buffer {} does not exist (the file has {})",
                                             bv.buffer, model.buffers.size()));
    }
    const tinygltf::Buffer& buffer = model.buffers[static_cast<std::size_t>(bv.buffer)];
    const std::size_t size = buffer.data.size();
    if (bv.byteOffset > size || bv.byteLength > size - bv.byteOffset) {
      return ctx.invalid(object,
                         fmt::format("byteOffset {} + byteLength {} exceed {} ({} bytes)",
                                     bv.byteOffset, bv.byteLength,
                                     describe("buffer", bv.buffer, buffer.name), size));
    }
    if (bv.byteStride != 0 && (bv.byteStride < 4 || bv.byteStride > 252 || bv.byteStride % 4 != 0)) {
      return ctx.invalid(object, fmt::format("byteStride {} is not a multiple of 4 in [4, 252]",
                                             bv.byteStride));
    }
  }
  return Status::ok();
}

}  // namespace lightlink::scene::gltf
