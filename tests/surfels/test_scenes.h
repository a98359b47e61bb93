// Hand-built scenes for the surfel and hierarchy tests: subdivided quads and boxes filled
// straight into scene::Scene, so these tests do not depend on the glTF loader.
#pragma once

#include <string>

#include <glm/glm.hpp>

#include "core/scene/scene.h"

namespace lightlink::testing {

// A parallelogram origin + s*u + t*v, s,t in [0,1], split into nu x nv cells of two
// triangles each, front face along cross(u, v). uv0 = uv1 = (s, t) unless `lightmap_uv` is off.
inline scene::MeshInstance quadMesh(const std::string& name, glm::vec3 origin, glm::vec3 u, glm::vec3 v,
                                    int nu, int nv, int material = -1, bool lightmap_uv = true) {
  scene::MeshInstance m;
  m.name = name;
  m.material = material;
  const glm::vec3 n = glm::normalize(glm::cross(u, v));
  for (int j = 0; j <= nv; ++j) {
    for (int i = 0; i <= nu; ++i) {
      const glm::vec2 st(float(i) / float(nu), float(j) / float(nv));
      m.positions.push_back(origin + st.x * u + st.y * v);
      m.normals.push_back(n);
      m.uv0.push_back(st);
      if (lightmap_uv) m.uv1.push_back(st);
    }
  }
  for (int j = 0; j < nv; ++j) {
    for (int i = 0; i < nu; ++i) {
      const std::uint32_t a = std::uint32_t(j * (nu + 1) + i), b = a + 1,
                          c = a + std::uint32_t(nu + 1), d = c + 1;
      m.indices.insert(m.indices.end(), {a, b, d, a, d, c});
    }
  }
  return m;
}

// Six outward-facing quads of an axis-aligned box [lo, hi], each nsub x nsub cells.
inline void addBox(scene::Scene& s, const std::string& name, glm::vec3 lo, glm::vec3 hi, int nsub,
                   int material = -1) {
  const glm::vec3 e = hi - lo;
  const glm::vec3 x(e.x, 0, 0), y(0, e.y, 0), z(0, 0, e.z);
  s.meshes.push_back(quadMesh(name + "/-z", lo, y, x, nsub, nsub, material));
  s.meshes.push_back(quadMesh(name + "/+z", lo + z, x, y, nsub, nsub, material));
  s.meshes.push_back(quadMesh(name + "/-y", lo, x, z, nsub, nsub, material));
  s.meshes.push_back(quadMesh(name + "/+y", lo + y, z, x, nsub, nsub, material));
  s.meshes.push_back(quadMesh(name + "/-x", lo, z, y, nsub, nsub, material));
  s.meshes.push_back(quadMesh(name + "/+x", lo + x, y, z, nsub, nsub, material));
}

// Fills bounds and scale the way the loader does.
inline void finishScene(scene::Scene& s) {
  s.bounds = Aabb{};
  for (const auto& m : s.meshes)
    for (const auto& p : m.positions) s.bounds.grow(p);
  s.scale = s.bounds.empty() ? 1.0f : std::max(s.bounds.diagonal(), 1e-6f);
}

inline double staticArea(const scene::Scene& s) {
  double a = 0.0;
  for (const auto& m : s.meshes) {
    if (!m.is_static) continue;
    for (std::size_t t = 0; t < m.indices.size(); t += 3) {
      const glm::dvec3 p0 = m.positions[m.indices[t]], p1 = m.positions[m.indices[t + 1]],
                       p2 = m.positions[m.indices[t + 2]];
      a += 0.5 * glm::length(glm::cross(p1 - p0, p2 - p0));
    }
  }
  return a;
}

}  // namespace lightlink::testing
