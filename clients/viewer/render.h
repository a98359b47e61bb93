// A small CPU viewer: renders a camera view of a scene the way a game client would light it
// from lightlink's outputs — static lightmapped surfaces from the SH lightmap (bilinear, with
// baked direct light), dynamic objects from the SH grid (trilinear) plus the direct light of
// every light with a shadow ray, realtime (non-baked) lights added on static surfaces too,
// emissive materials as their radiance. Primary visibility and shadows are traced with
// Embree; shading is Lambertian (albedo / pi * irradiance). Output is tone-mapped 8-bit sRGB.
// This is how people (and tests) see whether a bake is right.
#pragma once

#include <cstdint>
#include <vector>

#include <glm/glm.hpp>

#include "clients/viewer/baked_lighting.h"
#include "core/relight/light_set.h"
#include "core/rt/accel.h"
#include "core/scene/scene.h"

namespace lightlink::viewer {

struct Camera {
  glm::vec3 eye{0.0f, 0.0f, -1.0f};
  glm::vec3 target{0.0f};
  glm::vec3 up{0.0f, 1.0f, 0.0f};
  float vertical_fov_deg = 40.0f;
};

// A view from the -z side of the scene bounds looking at their centre (the open side of the
// Cornell box), far enough back for the whole box to fit the field of view.
Camera defaultCamera(const scene::Scene& scene);

struct RenderOptions {
  int width = 512;
  int height = 512;
  float exposure = 0.0f;  // scale before tone mapping; 0 = auto (mean lit pixel -> 0.5)
};

struct RenderStats {
  std::size_t lightmap_pixels = 0;  // lit from the lightmap
  std::size_t grid_pixels = 0;      // lit from the grid
  std::size_t unlit_pixels = 0;     // hit geometry that neither covers
  std::size_t background_pixels = 0;
  std::size_t shadow_rays = 0;
  double seconds = 0.0;
};

// `accel` must contain the dynamic meshes too (AccelOptions::static_only = false).
// `rgb` receives width * height * 3 bytes, top row first.
Expected<RenderStats> render(const scene::Scene& scene, const rt::Accel& accel, const BakedLighting& baked,
                             const relight::LightSet& lights, const Camera& camera, const RenderOptions& options,
                             std::vector<std::uint8_t>& rgb);

}  // namespace lightlink::viewer
