#include "core/scene/gltf_materials.h"

#include <cmath>
#include <cstdint>
#include <limits>

#include <stb/stb_image.h>

namespace lightlink::scene::gltf {

bool decodeImage(tinygltf::Image* image, int image_index, std::string* err, std::string* warn,
                 int req_width, int req_height, const unsigned char* bytes, int size,
                 void* user_data) {
  auto* state = static_cast<ImageDecodeState*>(user_data);
  const std::string object = describe("image", image_index, image->name);
  if (image->bufferView >= 0) {
    // tinygltf hands us &buffer.data[bufferView.byteOffset] unchecked: check the range
    // before reading anything.
    const tinygltf::Model& model = *state->model;
    const auto view_index = static_cast<std::size_t>(image->bufferView);
    const tinygltf::BufferView& bv = model.bufferViews[view_index];  // tinygltf checked the index
    const tinygltf::Buffer& buffer = model.buffers[static_cast<std::size_t>(bv.buffer)];
    if (bv.byteOffset > buffer.data.size() || bv.byteLength > buffer.data.size() - bv.byteOffset) {
      state->fatal = fmt::format("{}: bufferView {} (byteOffset {}, byteLength {}) exceeds buffer "
                                 "{} ({} bytes)",
                                 object, image->bufferView, bv.byteOffset, bv.byteLength,
                                 bv.buffer, buffer.data.size());
      if (err) *err += state->fatal + "\n";
      return false;
    }
  }
  if (!state->decode) return true;
  // The size from the header, before a byte is inflated: stb decodes to RGBA (16-bit
  // images at 2 bytes a channel) and loadTextures keeps an RGBA8 copy.
  int w = 0, h = 0, channels = 0;
  if (size > 0 && stbi_info_from_memory(bytes, size, &w, &h, &channels) && w > 0 && h > 0) {
    const std::uint64_t pixels = std::uint64_t(w) * std::uint64_t(h);
    const std::uint64_t depth = stbi_is_16_bit_from_memory(bytes, size) ? 2 : 1;
    const std::uint64_t cost = pixels * 4 * depth + pixels * 4;
    if (state->max_image_pixels != 0 && pixels > state->max_image_pixels) {
      state->over_budget = fmt::format("{}: {}x{} = {} pixels is above the limit of {} pixels per image "
                                       "(max_image_pixels)", object, w, h, pixels, state->max_image_pixels);
    } else if (state->max_image_bytes != 0 && state->decoded_bytes + cost > state->max_image_bytes) {
      state->over_budget = fmt::format("{}: decoding it ({}x{}) brings the decoded images to {} MiB, above the "
                                       "limit of {} MiB (max_image_bytes)", object, w, h,
                                       (state->decoded_bytes + cost) >> 20, state->max_image_bytes >> 20);
    }
    if (!state->over_budget.empty()) {
      if (err) *err += state->over_budget + "\n";
      return false;
    }
    state->decoded_bytes += cost;
  }
  std::string decode_err;
  if (!tinygltf::LoadImageData(image, image_index, &decode_err, warn, req_width, req_height,
                               bytes, size, nullptr)) {
    state->problems.push_back(fmt::format("{}: cannot be decoded ({})", object, decode_err));
    image->image.clear();
    image->width = image->height = -1;
  }
  return true;
}

namespace {

Status checkFactors(const Context& ctx, const std::string& object, const char* field,
                    const std::vector<double>& values, std::size_t expected) {
  if (values.size() != expected) {
    return ctx.invalid(object, fmt::format("{} has {} numbers, expected {}", field, values.size(),
                                           expected));
  }
  // The upper limit: finite in the file's double but +Inf in the float the Scene stores
  // (e.g. 1e39) is as unusable as Inf itself (tests/stability, DESIGN.md sec 6).
  constexpr double kFloatMax = double(std::numeric_limits<float>::max());
  for (std::size_t i = 0; i < values.size(); ++i) {
    if (!std::isfinite(values[i]) || values[i] < 0.0 || values[i] > kFloatMax) {
      return ctx.invalid(object, fmt::format("{}[{}] = {} is not a finite non-negative number",
                                             field, i, values[i]));
    }
  }
  return Status::ok();
}

Status checkScalar(const Context& ctx, const std::string& object, const char* field, double v) {
  if (!std::isfinite(v) || v < 0.0 || v > double(std::numeric_limits<float>::max())) {
    return ctx.invalid(object, fmt::format("{} = {} is not a finite non-negative number", field, v));
  }
  return Status::ok();
}

Expected<TextureRef> textureRef(const Context& ctx, const std::string& object, const char* field,
                                const tinygltf::TextureInfo& info) {
  TextureRef ref;
  if (info.index < 0) return ref;
  if (static_cast<std::size_t>(info.index) >= ctx.model.textures.size()) {
    return ctx.invalid(object, fmt::format("{} refers to texture {}, but the file has {}", field,
                                           info.index, ctx.model.textures.size()));
  }
  if (info.texCoord < 0 || info.texCoord > 1) {
    ctx.warn(object, fmt::format("{} uses TEXCOORD_{}; only sets 0 and 1 are read, so the "
                                 "texture is ignored", field, info.texCoord));
    return ref;
  }
  ref.texture = info.index;
  ref.texcoord = info.texCoord;
  return ref;
}

}  // namespace

Status loadTextures(const Context& ctx) {
  const tinygltf::Model& model = ctx.model;
  ctx.scene.textures.resize(model.textures.size());
  for (std::size_t i = 0; i < model.textures.size(); ++i) {
    const tinygltf::Texture& gt = model.textures[i];
    Texture& t = ctx.scene.textures[i];
    const std::string object = describe("texture", static_cast<int>(i), gt.name);
    if (gt.sampler >= 0) {
      if (static_cast<std::size_t>(gt.sampler) >= model.samplers.size()) {
        return ctx.invalid(object, fmt::format("refers to sampler {}, but the file has {}",
                                               gt.sampler, model.samplers.size()));
      }
      const tinygltf::Sampler& s = model.samplers[static_cast<std::size_t>(gt.sampler)];
      t.wrap_s = s.wrapS;
      t.wrap_t = s.wrapT;
      t.nearest = s.magFilter == TINYGLTF_TEXTURE_FILTER_NEAREST;
    }
    if (gt.source < 0) {
      ctx.warn(object, "has no image source (an extension image format?); samples as white");
      t.name = gt.name;
      continue;
    }
    if (static_cast<std::size_t>(gt.source) >= model.images.size()) {
      return ctx.invalid(object, fmt::format("refers to image {}, but the file has {}", gt.source,
                                             model.images.size()));
    }
    const tinygltf::Image& image = model.images[static_cast<std::size_t>(gt.source)];
    t.name = !gt.name.empty() ? gt.name : !image.name.empty() ? image.name : image.uri;
    if (!ctx.options.load_textures) continue;
    if (image.image.empty() || image.width < 1 || image.height < 1) {
      ctx.warn(object, fmt::format("image {} was not decoded; the texture samples as white",
                                   gt.source));
      continue;
    }
    const auto w = static_cast<std::size_t>(image.width);
    const auto h = static_cast<std::size_t>(image.height);
    const auto comps = static_cast<std::size_t>(image.component);
    const std::size_t bytes_per = image.bits == 16 ? 2 : 1;
    if (comps < 1 || comps > 4 || image.image.size() < w * h * comps * bytes_per) {
      ctx.warn(object, fmt::format("image {} has an unexpected layout ({} channels, {} bits); "
                                   "the texture samples as white", gt.source, comps, image.bits));
      continue;
    }
    t.width = image.width;
    t.height = image.height;
    t.rgba8.assign(w * h * 4, 255);
    for (std::size_t p = 0; p < w * h; ++p) {
      for (std::size_t c = 0; c < comps; ++c) {
        const std::size_t src = (p * comps + c) * bytes_per;
        // 16-bit: most significant byte (little-endian from stb); rounding is below 8 bits.
        const std::uint8_t v = bytes_per == 2 ? image.image[src + 1] : image.image[src];
        if (comps <= 2 && c == 0) {
          t.rgba8[p * 4 + 0] = t.rgba8[p * 4 + 1] = t.rgba8[p * 4 + 2] = v;  // grey
        } else if (comps == 2) {
          t.rgba8[p * 4 + 3] = v;  // grey + alpha
        } else {
          t.rgba8[p * 4 + c] = v;
        }
      }
    }
  }
  return Status::ok();
}

Status loadMaterials(const Context& ctx) {
  const tinygltf::Model& model = ctx.model;
  ctx.scene.materials.resize(model.materials.size());
  for (std::size_t i = 0; i < model.materials.size(); ++i) {
    const tinygltf::Material& gm = model.materials[i];
    Material& m = ctx.scene.materials[i];
    const std::string object = describe("material", static_cast<int>(i), gm.name);
    const tinygltf::PbrMetallicRoughness& pbr = gm.pbrMetallicRoughness;
    m.name = gm.name;

    if (Status s = checkFactors(ctx, object, "baseColorFactor", pbr.baseColorFactor, 4); !s) return s;
    m.base_color_factor = glm::vec4(pbr.baseColorFactor[0], pbr.baseColorFactor[1],
                                    pbr.baseColorFactor[2], pbr.baseColorFactor[3]);
    Expected<TextureRef> base = textureRef(ctx, object, "baseColorTexture", pbr.baseColorTexture);
    if (!base) return base.status();
    m.base_color_texture = *base;

    if (!gm.emissiveFactor.empty()) {
      if (Status s = checkFactors(ctx, object, "emissiveFactor", gm.emissiveFactor, 3); !s) return s;
      m.emissive_factor = glm::vec3(gm.emissiveFactor[0], gm.emissiveFactor[1], gm.emissiveFactor[2]);
    }
    Expected<TextureRef> emissive = textureRef(ctx, object, "emissiveTexture", gm.emissiveTexture);
    if (!emissive) return emissive.status();
    m.emissive_texture = *emissive;

    const auto strength_ext = gm.extensions.find("KHR_materials_emissive_strength");
    if (strength_ext != gm.extensions.end()) {
      const tinygltf::Value& ext = strength_ext->second;
      if (ext.IsObject() && ext.Has("emissiveStrength")) {
        const tinygltf::Value& v = ext.Get("emissiveStrength");
        if (!v.IsNumber()) {
          return ctx.invalid(object, "KHR_materials_emissive_strength.emissiveStrength is not a number");
        }
        const double strength = v.GetNumberAsDouble();
        if (Status s = checkScalar(ctx, object, "KHR_materials_emissive_strength.emissiveStrength",
                                   strength); !s) {
          return s;
        }
        m.emissive_strength = static_cast<float>(strength);
      }
    }

    if (Status s = checkScalar(ctx, object, "metallicFactor", pbr.metallicFactor); !s) return s;
    if (Status s = checkScalar(ctx, object, "roughnessFactor", pbr.roughnessFactor); !s) return s;
    m.metallic = static_cast<float>(pbr.metallicFactor);
    m.roughness = static_cast<float>(pbr.roughnessFactor);
    m.double_sided = gm.doubleSided;

    if (gm.alphaMode == "BLEND") {
      ctx.warn(object, "alphaMode BLEND is treated as opaque");
    }
  }
  return Status::ok();
}

}  // namespace lightlink::scene::gltf
