// Shadow maps for the GPU surfel lighting: the static scene rasterised from each light.
//
// Point lights get six views (a cube, faces +x, -x, +y, -y, +z, -z, each slightly wider
// than 90 degrees so 3x3 filtering at a face edge reads real texels), spot lights one
// perspective view around the cone (a cube when the cone is wider than 120 degrees) and
// directional lights one orthographic view covering the scene's bounding sphere. Every view
// is one layer of an R32F array texture holding a metric depth: the distance to the light
// (point, spot) or along the light direction (directional), so the compute shader compares
// metres, with biases relative to the texel footprint and the scene size (docs/gpu.md).
// Both faces of every static triangle are drawn, as the CPU's shadow rays stop at either.
#pragma once

#include <memory>
#include <span>
#include <vector>

#include "core/common/status.h"
#include "core/scene/scene.h"
#include "gpu/gl_objects.h"
#include "shaders/gpu_layout.h"

namespace lightlink::gpu {

class ShadowMaps {
 public:
  // Uploads the static triangles; `resolution` texels per view side (>= 16).
  static Expected<std::unique_ptr<ShadowMaps>> create(const scene::Scene& scene, int resolution);
  ~ShadowMaps();

  // Renders the views of every light with `emits[i]` and fills `lights[i].kind_views.yz`
  // (first view, count; 0 views for a dark light) and `views`. Needs a current context.
  Status render(std::span<const scene::Light> lights, std::span<const std::uint8_t> emits,
                std::span<glsl::GpuLight> gpu_lights, std::vector<glsl::GpuShadowView>& views);
  unsigned texture() const { return color_.id(); }
  int resolution() const { return resolution_; }
  std::size_t triangles() const { return index_count_ / 3; }

 private:
  ShadowMaps() = default;
  int resolution_ = 0;
  int layers_ = 0;  // allocated layers of color_
  glm::vec3 centre_{0.0f};
  float radius_ = 1.0f;
  std::size_t index_count_ = 0;
  GlBuffer vertices_, indices_;
  unsigned vao_ = 0;
  GlProgram program_;
  GlTexture color_, depth_;
  GlFramebuffer fbo_;
};

}  // namespace lightlink::gpu
