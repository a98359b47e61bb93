// What Embree's filter functions test on a hit (internal to core/rt): a mesh's alpha cut-out
// (glTF alphaMode MASK, and BLEND traced as a mask at 0.5) and its cast_shadows flag.
//
// A hit on a cut-out mesh is kept only where the base colour's alpha (factor * texture, at the
// texture's own TEXCOORD set) reaches the threshold; the others are rejected so the ray goes on.
// A mesh that casts no shadows is invisible to occlusion queries (shadow rays) only. Both are
// pure functions of the hit, so every trace stays deterministic. The Accel owns copies (the
// texture's alpha plane only), so the Scene may be freed after build().
#pragma once

#include <cstdint>
#include <memory>
#include <vector>

#include <glm/glm.hpp>

#include "core/scene/scene.h"

namespace lightlink::rt {

// One texture's alpha channel, sampled as Texture::sampleSrgb samples it (bilinear unless
// NEAREST, glTF wrap modes, texel centres at (i + 0.5) / size).
struct AlphaPlane {
  int width = 0, height = 0;
  int wrap_s = 10497, wrap_t = 10497;
  bool nearest = false;
  std::vector<std::uint8_t> alpha;  // width * height

  // Null when the texture has no decoded alpha (then only the factor counts).
  static std::shared_ptr<const AlphaPlane> fromTexture(const scene::Texture& texture);
  float sample(glm::vec2 uv) const;
};

struct SurfaceFilter {
  bool cutout = false;        // test alpha on every hit
  bool cast_shadows = true;   // false: occlusion queries ignore the mesh
  float alpha_factor = 1.0f;  // baseColorFactor.a
  float threshold = 0.5f;     // opaque where alpha >= threshold
  std::shared_ptr<const AlphaPlane> texture;  // null: the factor alone
  std::vector<glm::vec2> uv;                  // per vertex, the texture's TEXCOORD set
  std::vector<std::uint32_t> indices;         // copy of the mesh's, for the uv lookup

  // The filter a mesh needs, or null when every hit counts for every query.
  static std::unique_ptr<SurfaceFilter> forMesh(const scene::Scene& scene, const scene::MeshInstance& mesh,
                                                std::vector<std::shared_ptr<const AlphaPlane>>& planes);
  // True where the surface is there (not cut out) at barycentrics (u, v) of `triangle`.
  bool opaqueAt(std::uint32_t triangle, float u, float v) const;
};

}  // namespace lightlink::rt
