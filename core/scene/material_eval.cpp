#include "core/scene/material_eval.h"

#include "core/common/check.h"

namespace lightlink::scene {
namespace {

glm::vec3 textureRgb(const Scene& scene, const MeshInstance& mesh, const TextureRef& ref,
                     std::uint32_t triangle, glm::vec2 barycentric) {
  if (!ref.valid()) return glm::vec3(1.0f);
  const std::vector<glm::vec2>& uvs = ref.texcoord == 1 ? mesh.uv1 : mesh.uv0;
  if (uvs.empty()) return glm::vec3(1.0f);
  const Texture& texture = scene.textures[static_cast<std::size_t>(ref.texture)];
  return glm::vec3(texture.sampleSrgb(texcoordAt(mesh, ref.texcoord, triangle, barycentric)));
}

}  // namespace

glm::vec2 texcoordAt(const MeshInstance& mesh, int set, std::uint32_t triangle,
                     glm::vec2 barycentric) {
  const std::vector<glm::vec2>& uvs = set == 1 ? mesh.uv1 : mesh.uv0;
  if (uvs.empty()) return glm::vec2(0.0f);
  LL_CHECK_LT(std::size_t{triangle}, mesh.triangleCount());
  const std::uint32_t* i = &mesh.indices[std::size_t{triangle} * 3];
  return (1.0f - barycentric.x - barycentric.y) * uvs[i[0]] + barycentric.x * uvs[i[1]] +
         barycentric.y * uvs[i[2]];
}

glm::vec3 albedoAt(const Scene& scene, const MeshInstance& mesh, std::uint32_t triangle,
                   glm::vec2 barycentric) {
  const Material& m = scene.materialOf(mesh);
  return glm::vec3(m.base_color_factor) *
         textureRgb(scene, mesh, m.base_color_texture, triangle, barycentric);
}

glm::vec3 emissionAt(const Scene& scene, const MeshInstance& mesh, std::uint32_t triangle,
                     glm::vec2 barycentric) {
  const Material& m = scene.materialOf(mesh);
  if (!m.isEmissive()) return glm::vec3(0.0f);
  return m.emissive_factor * m.emissive_strength *
         textureRgb(scene, mesh, m.emissive_texture, triangle, barycentric);
}

glm::vec3 bounceAlbedoAt(const Scene& scene, const MeshInstance& mesh, std::uint32_t triangle, glm::vec2 barycentric) {
  return mesh.contribute_gi ? albedoAt(scene, mesh, triangle, barycentric) : glm::vec3(0.0f);
}

float alphaAt(const Scene& scene, const MeshInstance& mesh, std::uint32_t triangle, glm::vec2 barycentric) {
  const Material& m = scene.materialOf(mesh);
  const TextureRef& ref = m.base_color_texture;
  const std::vector<glm::vec2>& uvs = ref.texcoord == 1 ? mesh.uv1 : mesh.uv0;
  if (!ref.valid() || uvs.empty()) return m.base_color_factor.w;
  const Texture& texture = scene.textures[static_cast<std::size_t>(ref.texture)];
  return m.base_color_factor.w * texture.sampleSrgb(texcoordAt(mesh, ref.texcoord, triangle, barycentric)).w;
}

bool cutOutAt(const Scene& scene, const MeshInstance& mesh, std::uint32_t triangle, glm::vec2 barycentric) {
  const Material& m = scene.materialOf(mesh);
  return m.hasCutout() && alphaAt(scene, mesh, triangle, barycentric) < m.cutoutThreshold();
}

}  // namespace lightlink::scene
