// Small scenes built in code plus their precomputation, for the relight and output tests.
#pragma once

#include <optional>
#include <string>

#include <gtest/gtest.h>

#include "core/precompute/precompute.h"
#include "core/relight/relight.h"
#include "core/rt/accel.h"

namespace lightlink::relight::testing {

inline void addQuad(scene::Scene& s, glm::vec3 p0, glm::vec3 p1, glm::vec3 p2, glm::vec3 p3, int material) {
  scene::MeshInstance m;
  m.name = fmt::format("quad{}", s.meshes.size());
  m.positions = {p0, p1, p2, p3};
  const glm::vec3 n = glm::normalize(glm::cross(p1 - p0, p2 - p0));
  m.normals = {n, n, n, n};
  m.indices = {0, 1, 2, 0, 2, 3};
  m.material = material;
  s.meshes.push_back(m);
}

// Axis-aligned box; inward = true gives a room (faces point inside).
inline void addBox(scene::Scene& s, glm::vec3 lo, glm::vec3 hi, bool inward, int material) {
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

inline int addMaterial(scene::Scene& s, glm::vec3 albedo, glm::vec3 emission = glm::vec3(0.0f)) {
  scene::Material m;
  m.name = fmt::format("m{}", s.materials.size());
  m.base_color_factor = glm::vec4(albedo, 1.0f);
  m.emissive_factor = emission;
  s.materials.push_back(m);
  return int(s.materials.size()) - 1;
}

inline void finish(scene::Scene& s) {
  s.source_path = "test-scene";
  s.bounds = Aabb();
  for (const auto& m : s.meshes)
    for (const auto& p : m.positions) s.bounds.grow(p);
  s.scale = s.bounds.diagonal();
}

// Scene + accel + precomputation, in the order precompute builds them.
struct Baked {
  scene::Scene scene;
  std::optional<rt::Accel> accel;
  precompute::Precomputation p;

  static std::unique_ptr<Baked> make(scene::Scene s, precompute::PrecomputeOptions o) {
    auto b = std::make_unique<Baked>();
    finish(s);
    b->scene = std::move(s);
    auto p = precompute::run(b->scene, o);
    EXPECT_TRUE(p) << p.status().toString();
    if (!p) return nullptr;
    b->p = std::move(p).value();
    auto a = rt::Accel::build(b->scene);
    EXPECT_TRUE(a) << a.status().toString();
    b->accel.emplace(std::move(a).value());
    return b;
  }

  Relighter relighter() const {
    auto r = Relighter::create(scene, *accel, p);
    EXPECT_TRUE(r) << r.status().toString();
    return std::move(r).value();
  }
};

inline precompute::PrecomputeOptions smallOptions() {
  precompute::PrecomputeOptions o;
  o.surfels = 2048;
  o.links = 64;
  o.rays = 256;
  o.lightmap_resolution = 32;
  o.validity_rays = 16;
  o.builder = hierarchy::Builder::kKdMedian;
  return o;
}

}  // namespace lightlink::relight::testing
