#include "core/rt/cutout.h"

#include <cmath>

#include "core/scene/texture_wrap.h"

namespace lightlink::rt {
namespace {

using scene::wrap::foldCoordinate;
using scene::wrap::kMirroredRepeat;
using scene::wrap::kRepeat;
using scene::wrap::wrapTexel;

}  // namespace

std::shared_ptr<const AlphaPlane> AlphaPlane::fromTexture(const scene::Texture& texture) {
  if (texture.channels != 4 || texture.width <= 0 || texture.height <= 0 ||
      texture.rgba8.size() < std::size_t(texture.width) * std::size_t(texture.height) * 4)
    return nullptr;
  auto plane = std::make_shared<AlphaPlane>();
  plane->width = texture.width;
  plane->height = texture.height;
  plane->wrap_s = texture.wrap_s;
  plane->wrap_t = texture.wrap_t;
  plane->nearest = texture.nearest;
  plane->alpha.resize(std::size_t(texture.width) * std::size_t(texture.height));
  for (std::size_t i = 0; i < plane->alpha.size(); ++i) plane->alpha[i] = texture.rgba8[4 * i + 3];
  return plane;
}

float AlphaPlane::sample(glm::vec2 uv) const {
  const auto texel = [&](int x, int y) { return alpha[std::size_t(y) * std::size_t(width) + std::size_t(x)] / 255.0f; };
  const float x = foldCoordinate(uv.x, wrap_s) * float(width) - 0.5f;
  const float y = foldCoordinate(uv.y, wrap_t) * float(height) - 0.5f;
  if (nearest)
    return texel(wrapTexel(int(std::floor(x + 0.5f)), width, wrap_s), wrapTexel(int(std::floor(y + 0.5f)), height, wrap_t));
  const float fx = std::floor(x), fy = std::floor(y);
  const float tx = x - fx, ty = y - fy;
  const int x0 = int(fx), y0 = int(fy);
  const int xa = wrapTexel(x0, width, wrap_s), xb = wrapTexel(x0 + 1, width, wrap_s);
  const int ya = wrapTexel(y0, height, wrap_t), yb = wrapTexel(y0 + 1, height, wrap_t);
  const float top = texel(xa, ya) + (texel(xb, ya) - texel(xa, ya)) * tx;
  const float bottom = texel(xa, yb) + (texel(xb, yb) - texel(xa, yb)) * tx;
  return top + (bottom - top) * ty;
}

std::unique_ptr<SurfaceFilter> SurfaceFilter::forMesh(const scene::Scene& scene, const scene::MeshInstance& mesh,
                                                      std::vector<std::shared_ptr<const AlphaPlane>>& planes) {
  const scene::Material* material =
      mesh.material >= 0 && std::size_t(mesh.material) < scene.materials.size() ? &scene.materials[std::size_t(mesh.material)]
                                                                               : nullptr;
  const bool cutout = material != nullptr && material->hasCutout();
  if (!cutout && mesh.cast_shadows) return nullptr;
  auto f = std::make_unique<SurfaceFilter>();
  f->cast_shadows = mesh.cast_shadows;
  if (!cutout) return f;
  f->cutout = true;
  f->alpha_factor = material->base_color_factor.w;
  f->threshold = material->cutoutThreshold();
  const scene::TextureRef& ref = material->base_color_texture;
  const auto& uv = ref.texcoord == 1 ? mesh.uv1 : mesh.uv0;
  if (ref.valid() && std::size_t(ref.texture) < scene.textures.size() && (ref.texcoord == 0 || ref.texcoord == 1) &&
      uv.size() == mesh.positions.size()) {
    if (planes.size() < scene.textures.size()) planes.resize(scene.textures.size());
    auto& plane = planes[std::size_t(ref.texture)];
    if (!plane) plane = AlphaPlane::fromTexture(scene.textures[std::size_t(ref.texture)]);
    f->texture = plane;
    if (f->texture) {
      f->uv = uv;
      f->indices = mesh.indices;
    }
  }
  return f;
}

bool SurfaceFilter::opaqueAt(std::uint32_t triangle, float u, float v) const {
  if (!cutout) return true;
  float a = alpha_factor;
  if (texture) {
    const std::uint32_t* idx = &indices[3 * std::size_t(triangle)];
    const glm::vec2 st = (1.0f - u - v) * uv[idx[0]] + u * uv[idx[1]] + v * uv[idx[2]];
    a *= texture->sample(st);
  }
  return a >= threshold;
}

}  // namespace lightlink::rt
