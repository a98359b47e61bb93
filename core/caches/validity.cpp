#include <algorithm>
#include <limits>
#include <vector>

#include "core/caches/caches.h"
#include "core/common/sampling.h"

namespace lightlink::caches {

float backfaceFraction(const scene::Scene& scene, const rt::Accel& accel, const glm::vec3& p,
                       const glm::vec3& normal, const ValidityOptions& options, float contact_m) {
  return probeBackfaces(scene, accel, p, normal, options, 0.0f, contact_m).fraction;
}

BackfaceProbe probeBackfaces(const scene::Scene& scene, const rt::Accel& accel, const glm::vec3& p,
                             const glm::vec3& normal, const ValidityOptions& options, float near_m,
                             float contact_m) {
  const bool hemisphere = glm::dot(normal, normal) > 0.0f;
  const auto strata = static_cast<std::uint32_t>(std::max(1.0, std::floor(std::sqrt(options.rays))));
  const std::uint32_t count = strata * strata;
  glm::vec3 t(1, 0, 0), b(0, 1, 0), n(0, 0, 1);
  if (hemisphere) {
    n = glm::normalize(normal);
    orthonormalBasis(n, t, b);
  }
  // Thread-local scratch: this runs once per cache inside parallel loops.
  thread_local std::vector<rt::Ray> rays;
  thread_local std::vector<rt::Hit> hits;
  rays.resize(count);
  hits.resize(count);
  for (std::uint32_t i = 0; i < count; ++i) {
    const glm::vec2 u = stratifiedSample(i, strata, options.seed);
    const glm::vec3 local = hemisphere ? uniformHemisphere(u.x, u.y) : uniformSphere(u.x, u.y);
    const glm::vec3 dir = local.x * t + local.y * b + local.z * n;
    rays[i].dir = dir;
    rays[i].origin = hemisphere ? accel.offsetOrigin(p, n, dir) : p;
    rays[i].tnear = 0.0f;
    rays[i].tfar = std::numeric_limits<float>::infinity();
  }
  accel.intersect(rays, hits, rt::Coherence::kCoherent);
  std::uint32_t back = 0, near = 0;
  float reach = 0.0f;
  for (std::uint32_t i = 0; i < count; ++i) {
    const rt::Hit& h = hits[i];
    reach = std::max(reach, h.hit() ? h.t : std::numeric_limits<float>::infinity());
    if (!h.hit() || !h.backFacing(rays[i].dir)) continue;
    // A double-sided surface has no inside: seeing its back is seeing a surface, unless the
    // ray starts on it (contact_m).
    if (scene.materialOf(scene.meshes[h.mesh]).double_sided && !(h.t < contact_m)) continue;
    ++back;
    if (h.t < near_m) ++near;
  }
  return {static_cast<float>(back) / static_cast<float>(count), static_cast<float>(near) / static_cast<float>(count),
          reach};
}

}  // namespace lightlink::caches
