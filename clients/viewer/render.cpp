#include "clients/viewer/render.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <numbers>

#include <tbb/parallel_for.h>

#include "core/common/png.h"
#include "core/scene/light_eval.h"
#include "core/scene/material_eval.h"

namespace lightlink::viewer {
namespace {

constexpr float kPi = std::numbers::pi_v<float>;

// Direct irradiance of one light at p (shading normal n, geometric normal ng), shadowed.
glm::vec3 shadowedDirect(const rt::Accel& accel, const scene::Light& light, const glm::vec3& p, const glm::vec3& n,
                         const glm::vec3& ng, std::size_t& shadow_rays) {
  const glm::vec3 e = scene::irradianceFrom(light, p, n);
  if (e.x <= 0.0f && e.y <= 0.0f && e.z <= 0.0f) return glm::vec3(0.0f);
  rt::Ray ray;
  if (light.kind == scene::Light::Kind::kDirectional) {
    ray.dir = -light.direction;
  } else {
    ray.dir = light.position - p;
    ray.tfar = 1.0f - 1e-4f;  // stop just short of the light (t in units of |dir|)
  }
  ray.origin = accel.offsetOrigin(p, ng, ray.dir);
  ++shadow_rays;
  return accel.occluded(ray) ? glm::vec3(0.0f) : e;
}

}  // namespace

Camera defaultCamera(const scene::Scene& scene) {
  const glm::vec3 c = scene.bounds.center(), ext = scene.bounds.extent();
  Camera cam;
  cam.vertical_fov_deg = 40.0f;
  const float half = 0.5f * std::max(ext.x, ext.y);
  const float dist = half / std::tan(0.5f * glm::radians(cam.vertical_fov_deg)) * 1.05f;
  cam.target = c;
  cam.eye = glm::vec3(c.x, c.y, scene.bounds.min.z - dist);
  return cam;
}

Expected<RenderStats> render(const scene::Scene& scene, const rt::Accel& accel, const BakedLighting& baked,
                             const relight::LightSet& lights, const Camera& camera, const RenderOptions& options,
                             std::vector<std::uint8_t>& rgb) {
  if (options.width < 1 || options.height < 1 || options.width > 16384 || options.height > 16384)
    return invalidInput("render size {}x{} is out of range (1..16384)", options.width, options.height);
  if (!(camera.vertical_fov_deg > 0.0f && camera.vertical_fov_deg < 179.0f))
    return invalidInput("--fov {} must be in (0, 179) degrees", camera.vertical_fov_deg);
  const glm::vec3 forward = camera.target - camera.eye;
  if (!(glm::length(forward) > 0.0f) || !std::isfinite(glm::length(forward)))
    return invalidInput("camera eye and target must differ and be finite");
  const auto t0 = std::chrono::steady_clock::now();
  const glm::vec3 w = glm::normalize(forward);
  glm::vec3 u = glm::cross(w, camera.up);
  if (glm::length(u) < 1e-6f) u = glm::cross(w, glm::vec3(1, 0, 0));
  u = glm::normalize(u);
  const glm::vec3 v = glm::cross(u, w);
  const float tan_half = std::tan(0.5f * glm::radians(camera.vertical_fov_deg));
  const float aspect = float(options.width) / float(options.height);

  const std::size_t pixels = std::size_t(options.width) * options.height;
  std::vector<glm::vec3> radiance(pixels, glm::vec3(0.0f));
  std::vector<std::uint8_t> kind(pixels, 0);  // 0 background, 1 lightmap, 2 grid, 3 unlit
  std::atomic<std::size_t> shadow_rays{0};
  tbb::parallel_for(0, options.height, [&](int y) {
    std::size_t rays = 0;
    for (int x = 0; x < options.width; ++x) {
      const float sx = (2.0f * (float(x) + 0.5f) / float(options.width) - 1.0f) * tan_half * aspect;
      const float sy = (1.0f - 2.0f * (float(y) + 0.5f) / float(options.height)) * tan_half;
      rt::Ray ray;
      ray.origin = camera.eye;
      ray.dir = glm::normalize(w + sx * u + sy * v);
      const rt::Hit hit = accel.intersect(ray);
      const std::size_t px = std::size_t(y) * options.width + x;
      if (!hit.hit()) continue;
      const auto& mesh = scene.meshes[hit.mesh];
      const std::uint32_t* idx = &mesh.indices[3 * hit.triangle];
      const float b0 = 1.0f - hit.u - hit.v;
      const glm::vec3 p = ray.origin + hit.t * ray.dir;
      glm::vec3 ng = glm::normalize(hit.ng);
      glm::vec3 n = glm::normalize(b0 * mesh.normals[idx[0]] + hit.u * mesh.normals[idx[1]] + hit.v * mesh.normals[idx[2]]);
      // Shade the side the camera sees.
      if (glm::dot(ng, ray.dir) > 0.0f) ng = -ng;
      if (glm::dot(n, ng) < 0.0f) n = -n;
      const glm::vec2 bary(hit.u, hit.v);
      const glm::vec3 albedo = scene::albedoAt(scene, mesh, hit.triangle, bary);
      const glm::vec3 emission = scene::emissionAt(scene, mesh, hit.triangle, bary);
      glm::vec3 e(0.0f);
      bool from_lightmap = false;
      if (mesh.is_static && mesh.hasLightmapUv()) {
        const glm::vec2 uv = b0 * mesh.uv1[idx[0]] + hit.u * mesh.uv1[idx[1]] + hit.v * mesh.uv1[idx[2]];
        from_lightmap = baked.sampleLightmap(uv, n, e);
      }
      bool lit = from_lightmap;
      if (!from_lightmap) lit = baked.sampleGrid(p, n, e);
      // Direct light the lightmap does not hold: every light on grid-lit surfaces, realtime
      // (non-baked) lights on lightmapped ones.
      for (const auto& entry : lights.lights())
        if (!from_lightmap || !entry.baked) e += shadowedDirect(accel, entry.light, p, n, ng, rays);
      radiance[px] = albedo / kPi * e + emission;
      kind[px] = from_lightmap ? 1 : lit ? 2 : 3;
    }
    shadow_rays += rays;
  });

  RenderStats stats;
  std::vector<float> luminance;
  luminance.reserve(pixels);
  for (std::size_t i = 0; i < pixels; ++i) {
    switch (kind[i]) {
      case 0: ++stats.background_pixels; break;
      case 1: ++stats.lightmap_pixels; break;
      case 2: ++stats.grid_pixels; break;
      default: ++stats.unlit_pixels; break;
    }
    if (kind[i] != 0) luminance.push_back((radiance[i].x + radiance[i].y + radiance[i].z) / 3.0f);
  }
  // Auto exposure maps the median lit pixel to 0.5: a median, so a bright emitter filling
  // part of the frame does not darken the rest.
  float exposure = options.exposure;
  if (exposure <= 0.0f) {
    exposure = 1.0f;
    if (!luminance.empty()) {
      auto mid = luminance.begin() + static_cast<std::ptrdiff_t>(luminance.size() / 2);
      std::nth_element(luminance.begin(), mid, luminance.end());
      if (*mid > 0.0f) exposure = 1.0f / *mid;
    }
  }
  rgb.assign(pixels * 3, 0);
  for (std::size_t i = 0; i < pixels; ++i)
    for (int ch = 0; ch < 3; ++ch) {
      const float c = radiance[i][ch] * exposure;
      rgb[3 * i + ch] = kind[i] == 0 ? 0 : encodeSrgb8(c / (1.0f + c));  // Reinhard
    }
  stats.shadow_rays = shadow_rays.load();
  stats.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return stats;
}

}  // namespace lightlink::viewer
