#include "core/scene/gltf_materials.h"

#include <cmath>
#include <cstdint>
#include <limits>

#include <stb/stb_image.h>
#include <tbb/parallel_for.h>

namespace lightlink::scene::gltf {

bool queueImage(tinygltf::Image* image, int image_index, std::string* err, std::string* /*warn*/,
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
  const auto index = static_cast<std::size_t>(image_index);
  if (!state->decode || index >= state->wanted.size() || !state->wanted[index]) return true;
  // RGB where nothing reads alpha: a quarter less memory for most textures.
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
    } else if (state->max_image_bytes != 0 && state->budgeted_bytes + cost > state->max_image_bytes) {
      state->over_budget = fmt::format("{}: decoding it ({}x{}) brings the decoded images to {} MiB, above the "
                                       "limit of {} MiB (max_image_bytes)", object, w, h,
                                       (state->budgeted_bytes + cost) >> 20, state->max_image_bytes >> 20);
    }
    if (!state->over_budget.empty()) {
      if (err) *err += state->over_budget + "\n";
      return false;
    }
    state->budgeted_bytes += cost;
  }
  if (state->queue.size() <= index) state->queue.resize(index + 1);
  QueuedImage& queued = state->queue[index];
  queued.object = object;
  queued.keep_channels = keep;
  queued.encoded.assign(bytes, bytes + (size > 0 ? size : 0));
  return true;
}

void QueuedImage::freePixels(void* p) { stbi_image_free(p); }

void decodeQueuedImages(ImageDecodeState& state) {
  std::vector<std::string> problems(state.queue.size());
  tbb::parallel_for(std::size_t(0), state.queue.size(), [&](std::size_t i) {
    QueuedImage& q = state.queue[i];
    if (q.object.empty()) return;  // not queued
    int w = 0, h = 0, channels_in_file = 0;
    stbi_uc* data = q.encoded.empty()
                        ? nullptr
                        : stbi_load_from_memory(q.encoded.data(), static_cast<int>(q.encoded.size()), &w, &h,
                                                &channels_in_file, q.keep_channels);
    std::vector<unsigned char>().swap(q.encoded);
    q.pixels.reset(data);
    if (data == nullptr || w < 1 || h < 1) {
      const char* why = data == nullptr ? stbi_failure_reason() : nullptr;  // thread-local in stb
      problems[i] = fmt::format("{}: cannot be decoded ({}); the material's factor is used", q.object,
                                why != nullptr ? why : "no data");
      q.pixels.reset();
      return;
    }
    q.width = w;
    q.height = h;
    q.channels = q.keep_channels;
  });
  for (std::size_t i = 0; i < state.queue.size(); ++i) {
    if (!problems[i].empty()) state.problems.push_back(std::move(problems[i]));
    if (state.queue[i].pixels) {
      ++state.decoded;
      state.decoded_bytes += state.queue[i].bytes();
    }
  }
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
  // The last texture to use an image frees its decoded pixels.
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
    QueuedImage* decoded = source < images.queue.size() ? &images.queue[source] : nullptr;
    if (decoded == nullptr || !decoded->pixels) {
      ctx.warn(object, fmt::format("image {}{} was not decoded; the material's factor is used", gt.source,
                                   image.uri.empty() ? "" : " '" + image.uri + "'"));
      continue;
    }
    t.width = decoded->width;
    t.height = decoded->height;
    t.channels = decoded->channels;
    t.rgba8.assign(decoded->pixels.get(), decoded->pixels.get() + decoded->bytes());
    if (last_user[source] == static_cast<int>(i)) decoded->pixels.reset();  // no texture needs it any more
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
