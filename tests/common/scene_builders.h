// Small scenes built in code for unit tests: flat-shaded quads, axis-aligned boxes (a room
// with inward faces or a solid block with outward ones), Lambertian materials, and the
// bounds/scale a loader would fill in. (Names via fmt: GCC 12 gives a false -Wrestrict on
// "literal" + std::to_string at -O3.) One copy, shared by the links, relight and reference
// tests so their scenes mean the same thing.
#pragma once

#include <fmt/format.h>
#include <glm/glm.hpp>

#include "core/common/aabb.h"
#include "core/scene/scene.h"

namespace lightlink::testing {

// Quad p0..p3, counter-clockwise seen from its front (its normal), two triangles.
inline void addQuad(scene::Scene& s, glm::vec3 p0, glm::vec3 p1, glm::vec3 p2, glm::vec3 p3, int material = -1) {
  scene::MeshInstance m;
  m.name = fmt::format("quad{}", s.meshes.size());
  m.positions = {p0, p1, p2, p3};
  const glm::vec3 n = glm::normalize(glm::cross(p1 - p0, p2 - p0));
  m.normals = {n, n, n, n};
  m.indices = {0, 1, 2, 0, 2, 3};
  m.material = material;
  s.meshes.push_back(m);
}

// Axis-aligned box; inward = true gives a room (faces point inside), false a solid block.
inline void addBox(scene::Scene& s, glm::vec3 lo, glm::vec3 hi, bool inward, int material = -1) {
  const glm::vec3 c[8] = {{lo.x, lo.y, lo.z}, {hi.x, lo.y, lo.z}, {hi.x, hi.y, lo.z}, {lo.x, hi.y, lo.z},
                          {lo.x, lo.y, hi.z}, {hi.x, lo.y, hi.z}, {hi.x, hi.y, hi.z}, {lo.x, hi.y, hi.z}};
  const int faces[6][4] = {{0, 3, 2, 1}, {4, 5, 6, 7}, {0, 1, 5, 4}, {2, 3, 7, 6}, {0, 4, 7, 3}, {1, 2, 6, 5}};
  for (const auto& f : faces) {
    if (inward)
      addQuad(s, c[f[3]], c[f[2]], c[f[1]], c[f[0]], material);
    else
      addQuad(s, c[f[0]], c[f[1]], c[f[2]], c[f[3]], material);
  }
}

inline int addMaterial(scene::Scene& s, glm::vec3 albedo, glm::vec3 emission = glm::vec3(0.0f),
                       bool double_sided = false) {
  scene::Material m;
  m.name = fmt::format("m{}", s.materials.size());
  m.base_color_factor = glm::vec4(albedo, 1.0f);
  m.emissive_factor = emission;
  m.double_sided = double_sided;
  s.materials.push_back(m);
  return int(s.materials.size()) - 1;
}

// Bounds and scale, as loadGltf computes them.
inline void finishScene(scene::Scene& s) {
  s.bounds = Aabb();
  for (const auto& m : s.meshes)
    for (const auto& p : m.positions) s.bounds.grow(p);
  s.scale = s.bounds.diagonal();
}

}  // namespace lightlink::testing
