#include "core/reference/contact_band.h"

#include <cmath>

#include <glm/gtc/constants.hpp>
#include <tbb/parallel_for.h>

namespace lightlink::reference {

std::vector<std::uint8_t> nearContact(const rt::Accel& accel, std::span<const glm::vec3> positions,
                                      std::span<const glm::vec3> normals, std::span<const float> radius) {
  constexpr int kAzimuths = 8;
  constexpr float kElevationsDeg[] = {5.0f, 30.0f, 60.0f};
  const std::size_t n = std::min({positions.size(), normals.size(), radius.size()});
  std::vector<std::uint8_t> out(n, 0);
  tbb::parallel_for(std::size_t(0), n, [&](std::size_t i) {
    const glm::vec3 nrm = glm::normalize(normals[i]);
    // Any tangent frame will do: the fan is symmetric enough that its orientation does not matter.
    const glm::vec3 a = std::abs(nrm.x) < 0.9f ? glm::vec3(1, 0, 0) : glm::vec3(0, 1, 0);
    const glm::vec3 t = glm::normalize(glm::cross(nrm, a)), b = glm::cross(nrm, t);
    auto blocked = [&](const glm::vec3& dir) {
      rt::Ray ray;
      ray.origin = accel.offsetOrigin(positions[i], nrm, dir);
      ray.dir = dir;
      ray.tfar = radius[i];
      return accel.occluded(ray);
    };
    if (blocked(nrm)) {
      out[i] = 1;
      return;
    }
    for (const float deg : kElevationsDeg) {
      const float el = glm::radians(deg);
      for (int k = 0; k < kAzimuths; ++k) {
        const float az = 2.0f * glm::pi<float>() * (float(k) + 0.5f) / kAzimuths;
        const glm::vec3 dir = std::cos(el) * (std::cos(az) * t + std::sin(az) * b) + std::sin(el) * nrm;
        if (blocked(dir)) {
          out[i] = 1;
          return;
        }
      }
    }
  });
  return out;
}

float texelSizeOnTriangle(const scene::MeshInstance& mesh, std::uint32_t triangle, int width, int height) {
  if (!mesh.hasLightmapUv() || 3 * std::size_t(triangle) + 2 >= mesh.indices.size()) return 0.0f;
  const std::uint32_t* idx = &mesh.indices[3 * std::size_t(triangle)];
  const glm::vec2 size(width, height);
  const glm::vec2 t0 = mesh.uv1[idx[0]] * size, t1 = mesh.uv1[idx[1]] * size, t2 = mesh.uv1[idx[2]] * size;
  const glm::vec2 e1 = t1 - t0, e2 = t2 - t0;
  const float texel_area = std::abs(e1.x * e2.y - e1.y * e2.x);
  const glm::vec3 p0 = mesh.positions[idx[0]];
  const float world_area = glm::length(glm::cross(mesh.positions[idx[1]] - p0, mesh.positions[idx[2]] - p0));
  return texel_area > 0.0f ? std::sqrt(world_area / texel_area) : 0.0f;
}

}  // namespace lightlink::reference
