// A seeded random scene generator for the property sweep and the determinism test: a closed
// room (inward box) with random solid boxes, thin slabs and double-sided thin walls, random
// grey/coloured albedos (< 0.9, some surfaces emissive) and random point/spot lights, some
// of which end up inside geometry. The same seed always gives the same scene (std::mt19937_64
// with explicit uniform mapping, no std::uniform_real_distribution whose output is
// implementation-defined).
#pragma once

#include <cstdint>
#include <random>

#include <fmt/format.h>

#include "tests/stability/stability_fixture.h"

namespace lightlink::stability {

struct RandomScene {
  scene::Scene scene;
  LightSet lights;
  float max_albedo = 0.0f;
};

class SceneRng {
 public:
  explicit SceneRng(std::uint64_t seed) : rng_(seed) {}
  float uniform(float lo, float hi) { return lo + (hi - lo) * float(double(rng_() >> 11) * 0x1.0p-53); }
  int below(int n) { return int(rng_() % std::uint64_t(n)); }

 private:
  std::mt19937_64 rng_;
};

inline RandomScene makeRandomScene(std::uint64_t seed) {
  SceneRng r(seed);
  RandomScene out;
  scene::Scene& s = out.scene;
  auto material = [&](bool may_emit) {
    const glm::vec3 albedo(r.uniform(0.05f, 0.9f), r.uniform(0.05f, 0.9f), r.uniform(0.05f, 0.9f));
    out.max_albedo = std::max({out.max_albedo, albedo.x, albedo.y, albedo.z});
    const bool emit = may_emit && r.below(4) == 0;
    return addMaterial(s, albedo, emit ? glm::vec3(r.uniform(0.5f, 4.0f)) : glm::vec3(0.0f), r.below(3) == 0);
  };
  const glm::vec3 room(r.uniform(2.0f, 6.0f), r.uniform(1.5f, 4.0f), r.uniform(2.0f, 6.0f));
  addBox(s, {0, 0, 0}, room, /*inward=*/true, material(false));
  auto inside = [&](float margin) {
    return glm::vec3(r.uniform(margin, room.x - margin), r.uniform(margin, room.y - margin),
                     r.uniform(margin, room.z - margin));
  };
  const int boxes = 1 + r.below(3);
  for (int i = 0; i < boxes; ++i) {
    const glm::vec3 c = inside(0.3f);
    const glm::vec3 h(r.uniform(0.1f, 0.6f), r.uniform(0.1f, 0.6f), r.uniform(0.1f, 0.6f));
    addBox(s, glm::max(c - h, glm::vec3(0.0f)), glm::min(c + h, room), /*inward=*/false, material(true));
  }
  const int slabs = r.below(3);
  for (int i = 0; i < slabs; ++i) {  // thin horizontal slabs (tables, shelves): 1-5 mm thick
    const glm::vec3 c = inside(0.3f);
    const glm::vec3 h(r.uniform(0.2f, 0.8f), r.uniform(0.0005f, 0.0025f), r.uniform(0.2f, 0.8f));
    addBox(s, glm::max(c - h, glm::vec3(0.0f)), glm::min(c + h, room), /*inward=*/false, material(false));
  }
  const int walls = r.below(3);
  for (int i = 0; i < walls; ++i) {  // thin double-sided partitions, x = const
    const float x = r.uniform(0.3f, room.x - 0.3f);
    const float z0 = r.uniform(0.0f, room.z * 0.5f), z1 = r.uniform(room.z * 0.5f, room.z);
    const float y1 = r.uniform(0.5f, room.y);
    const int m = material(false);
    s.materials[std::size_t(m)].double_sided = true;
    addQuad(s, {x, 0, z0}, {x, y1, z0}, {x, y1, z1}, {x, 0, z1}, m);
  }
  const int lights = 1 + r.below(3);
  for (int i = 0; i < lights; ++i) {
    // fmt, not "l" + std::to_string(i): GCC 12 warns (-Wrestrict, a known false positive) on
    // operator+(const char*, string&&) inlined here.
    LightEntry e = pointLight(fmt::format("l{}", i), inside(0.05f), r.uniform(0.1f, 20.0f),
                              glm::vec3(r.uniform(0.2f, 1.0f), r.uniform(0.2f, 1.0f), r.uniform(0.2f, 1.0f)));
    if (r.below(3) == 0) {
      e.light.kind = scene::Light::Kind::kSpot;
      e.light.direction = glm::normalize(glm::vec3(r.uniform(-1, 1), -1.0f, r.uniform(-1, 1)));
      e.light.outer_cone_angle = r.uniform(0.3f, 1.2f);
      e.light.inner_cone_angle = 0.5f * e.light.outer_cone_angle;
    }
    e.baked = r.below(4) != 0;
    const bool added = bool(out.lights.add(e));
    EXPECT_TRUE(added);
  }
  relight::testing::finish(s);
  return out;
}

}  // namespace lightlink::stability
