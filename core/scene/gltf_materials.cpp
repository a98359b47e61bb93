#include "core/scene/gltf_materials.h"
#include "core/scene/gltf_nodes.h"

#include <cmath>
#include <cstdint>
#include <limits>

#include <stb/stb_image.h>

namespace lightlink::scene::gltf {

bool decodeImage(tinygltf::Image* image, int image_index, std::string* err, std::string* /*warn*/,
                 int /*req_width*/, int /*req_height*/, const unsigned char* bytes, int size,
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
  // Normal, metallic-roughness and occlusion maps, and unused images: never decoded.
  if (!state->decode || static_cast<std::size_t>(image_index) >= state->wanted.size() ||
      !state->wanted[static_cast<std::size_t>(image_index)])
    return true;
  // RGB where nothing reads alpha: a quarter less memory for most textures.
  const auto index = static_cast<std::size_t>(image_index);
  const int keep = index < state->alpha.size() && state->alpha[index] ? 4 : 3;
  // The size from the header, before a byte is inflated: what is kept is RGB(A)8 (16-bit
  // images are reduced by stb while decoding).
  int w = 0, h = 0, channels = 0;
  if (size > 0 && stbi_info_from_memory(bytes, size, &w, &h, &channels) && w > 0 && h > 0) {
    const std::uint64_t pixels = std::uint64_t(w) * std::uint64_t(h);
    const std::uint64_t cost = pixels * static_cast<std::uint64_t>(keep);
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
  }
  int got_w = 0, got_h = 0, got_channels = 0;
  stbi_uc* data = size > 0 ? stbi_load_from_memory(bytes, size, &got_w, &got_h, &got_channels, keep) : nullptr;
  if (data == nullptr || got_w < 1 || got_h < 1) {
    const char* why = size > 0 ? stbi_failure_reason() : nullptr;
    state->problems.push_back(fmt::format("{}: cannot be decoded ({}); the material's factor is used",
                                          object, why != nullptr ? why : "no data"));
    if (data != nullptr) stbi_image_free(data);
    image->width = image->height = -1;
    return true;
  }
  const std::size_t n = std::size_t(got_w) * std::size_t(got_h) * static_cast<std::size_t>(keep);
  if (state->pixels.size() <= index) {
    state->pixels.resize(index + 1);
    state->channels.resize(index + 1, 4);
  }
  state->pixels[index].assign(data, data + n);
  state->channels[index] = keep;
  stbi_image_free(data);
  state->decoded_bytes += n;
  ++state->decoded;
  image->width = got_w;
  image->height = got_h;
  image->component = keep;
  image->bits = 8;
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

Status loadTextures(const Context& ctx, ImageDecodeState& images) {
  const tinygltf::Model& model = ctx.model;
  ctx.scene.textures.resize(model.textures.size());
  // The last texture to use an image takes its pixels; earlier ones copy them.
  std::vector<int> last_user(model.images.size(), -1);
  for (std::size_t i = 0; i < model.textures.size(); ++i) {
    const int source = model.textures[i].source;
    if (!ctx.lighting.texture(static_cast<int>(i))) continue;
    if (source >= 0 && static_cast<std::size_t>(source) < model.images.size())
      last_user[static_cast<std::size_t>(source)] = static_cast<int>(i);
  }
  for (std::size_t i = 0; i < model.textures.size(); ++i) {
    const tinygltf::Texture& gt = model.textures[i];
    Texture& t = ctx.scene.textures[i];
    const std::string object = describe("texture", static_cast<int>(i), gt.name);
    const bool wanted = ctx.options.load_textures && images.decode;
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
      if (wanted && ctx.lighting.texture(static_cast<int>(i)))
        ctx.warn(object, "has no image source (an extension image format?); the material's factor is used");
      t.name = gt.name;
      continue;
    }
    if (static_cast<std::size_t>(gt.source) >= model.images.size()) {
      return ctx.invalid(object, fmt::format("refers to image {}, but the file has {}", gt.source,
                                             model.images.size()));
    }
    const auto source = static_cast<std::size_t>(gt.source);
    const tinygltf::Image& image = model.images[source];
    t.name = !gt.name.empty() ? gt.name : !image.name.empty() ? image.name : image.uri;
    if (!wanted || !ctx.lighting.texture(static_cast<int>(i))) continue;  // not sampled for lighting
    std::vector<std::uint8_t>* pixels = source < images.pixels.size() ? &images.pixels[source] : nullptr;
    const int channels = source < images.channels.size() ? images.channels[source] : 4;
    if (pixels == nullptr || pixels->empty() || image.width < 1 || image.height < 1 ||
        pixels->size() != std::size_t(image.width) * std::size_t(image.height) * std::size_t(channels)) {
      ctx.warn(object, fmt::format("image {}{} was not decoded; the material's factor is used", gt.source,
                                   image.uri.empty() ? "" : " '" + image.uri + "'"));
      continue;
    }
    t.width = image.width;
    t.height = image.height;
    t.channels = channels;
    if (last_user[source] == static_cast<int>(i)) t.rgba8 = std::move(*pixels);
    else t.rgba8 = *pixels;
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

    if (gm.alphaMode == "MASK") {
      if (Status s = checkScalar(ctx, object, "alphaCutoff", gm.alphaCutoff); !s) return s;
      m.alpha_mode = Material::AlphaMode::kMask;
      m.alpha_cutoff = static_cast<float>(gm.alphaCutoff);
    } else if (gm.alphaMode == "BLEND") {
      // No ray tracer traces partial coverage deterministically for free: BLEND is cut out
      // where it is less than half opaque (docs/scene-format.md "Alpha").
      m.alpha_mode = Material::AlphaMode::kBlend;
      ctx.warn(object, "alphaMode BLEND is traced as a cut-out at opacity 0.5 (no partial shadows); glass or a light "
                       "shaft that should not block light wants extras {\"lightlink\": {\"cast_shadows\": false}}");
    } else if (!gm.alphaMode.empty() && gm.alphaMode != "OPAQUE") {
      ctx.warn(object, fmt::format("alphaMode '{}' is not OPAQUE, MASK or BLEND; treated as OPAQUE", gm.alphaMode));
    }
    if (gm.extras.IsObject() && gm.extras.Has("lightlink")) {
      const tinygltf::Value& ours = gm.extras.Get("lightlink");
      if (!ours.IsObject()) return ctx.invalid(object, "extras.lightlink must be an object");
      if (ours.Has("cast_shadows")) {
        const tinygltf::Value& flag = ours.Get("cast_shadows");
        if (!flag.IsBool()) return ctx.invalid(object, "extras.lightlink.cast_shadows must be true or false");
        m.cast_shadows = flag.Get<bool>();
      }
      if (ours.Has("contribute_gi")) {
        const tinygltf::Value& flag = ours.Get("contribute_gi");
        if (!flag.IsBool()) return ctx.invalid(object, "extras.lightlink.contribute_gi must be true or false");
        m.contribute_gi = flag.Get<bool>();
      }
      if (ours.Has("receive_gi")) {
        Expected<int> r = parseReceiveGi(ctx, object, ours.Get("receive_gi"));
        if (!r) return r.status();
        m.receive_gi = *r;
      }
    }
  }
  return Status::ok();
}

}  // namespace lightlink::scene::gltf
