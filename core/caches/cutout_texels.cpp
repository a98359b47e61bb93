#include "core/caches/cutout_texels.h"

#include <atomic>

#include <tbb/parallel_for.h>

#include "core/scene/material_eval.h"

namespace lightlink::caches {
namespace {

// Barycentrics (Embree's u, v) of p projected onto triangle (a, b, c); the validity push may
// have lifted the cache off the surface, the projection brings it back.
glm::vec2 barycentricOf(const glm::vec3& p, const glm::vec3& a, const glm::vec3& b, const glm::vec3& c) {
  const glm::vec3 e1 = b - a, e2 = c - a, d = p - a;
  const float d11 = glm::dot(e1, e1), d12 = glm::dot(e1, e2), d22 = glm::dot(e2, e2);
  const float p1 = glm::dot(d, e1), p2 = glm::dot(d, e2);
  const float det = d11 * d22 - d12 * d12;
  if (!(det > 0.0f)) return glm::vec2(1.0f / 3.0f);
  return glm::vec2((d22 * p1 - d12 * p2) / det, (d11 * p2 - d12 * p1) / det);
}

}  // namespace

std::size_t invalidateCutoutTexels(const scene::Scene& scene, LightmapCaches& caches) {
  bool any = false;
  for (const auto& m : scene.materials) any |= m.hasCutout();
  if (!any) return 0;
  std::atomic<std::size_t> dropped{0};
  tbb::parallel_for(std::size_t(0), caches.size(), [&](std::size_t i) {
    if (!caches.valid[i]) return;
    const scene::MeshInstance& mesh = scene.meshes[caches.mesh[i]];
    if (!scene.materialOf(mesh).hasCutout()) return;
    const std::uint32_t* idx = &mesh.indices[3 * std::size_t(caches.triangle[i])];
    const glm::vec2 uv = barycentricOf(caches.position[i], mesh.positions[idx[0]], mesh.positions[idx[1]],
                                       mesh.positions[idx[2]]);
    if (scene::cutOutAt(scene, mesh, caches.triangle[i], uv)) {
      caches.valid[i] = 0;
      dropped.fetch_add(1, std::memory_order_relaxed);
    }
  });
  return dropped.load();
}

}  // namespace lightlink::caches
