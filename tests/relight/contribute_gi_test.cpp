// Issue 46: a mesh with contribute_gi false reflects no bounce light. A sun lights a floor
// and a wall standing on it; with the wall contributing, the floor's indirect light (the
// wall's bounce) is clearly non-zero; with contribute_gi false on the wall the floor's only
// indirect source is gone and its lightmap indirect is zero.
#include <gtest/gtest.h>

#include "core/sh/sh.h"
#include "tests/relight/relight_fixture.h"

namespace lightlink::relight::testing {
namespace {

double floorIndirect(bool wall_contributes) {
  scene::Scene s;
  const int grey = addMaterial(s, glm::vec3(0.8f));
  addQuad(s, {-1, 0, -1}, {-1, 0, 1}, {1, 0, 1}, {1, 0, -1}, grey);   // floor, facing +y
  addQuad(s, {0, 0, 1}, {0, 2, 1}, {0, 2, -1}, {0, 0, -1}, grey);     // wall at x = 0, facing -x
  s.meshes.back().contribute_gi = wall_contributes;
  scene::Light sun;
  sun.kind = scene::Light::Kind::kDirectional;
  sun.intensity = 10.0f;
  sun.direction = glm::normalize(glm::vec3(1, -1, 0));  // lights the floor and the wall's -x face
  s.lights.push_back(sun);
  auto baked = Baked::make(std::move(s), smallOptions());
  if (!baked) return -1.0;
  auto r = baked->relighter().relight(LightSet::fromSceneLights(baked->scene.lights), RelightOptions{});
  EXPECT_TRUE(r) << r.status().toString();
  if (!r) return -1.0;
  const auto& lm = baked->p.lightmap;
  const int nc = r->coeffCount();
  double sum = 0.0;
  std::size_t n = 0;
  for (std::size_t c = 0; c < lm.size(); ++c) {
    if (!lm.valid[c] || lm.mesh[c] != 0 || lm.position[c].x > -0.05f) continue;  // floor in front of the wall
    const float* sh = r->lightmap_sh.data() + std::size_t(lm.texel[c]) * 3 * nc;
    sum += sh::irradiance(r->bands, sh + nc, lm.normal[c]);  // green
    ++n;
  }
  EXPECT_GT(n, 20u);
  return n ? sum / double(n) : -1.0;
}

TEST(ContributeGi, AWallThatContributesNoGiBouncesNoLightOntoTheFloor) {
  const double with = floorIndirect(true), without = floorIndirect(false);
  EXPECT_GT(with, 0.1);  // a 0.8 albedo wall lit at ~7 lux bounces about a lux onto the floor
  // Not exactly 0: SH ringing and clusters that mix wall and floor surfels leave ~2e-4.
  EXPECT_LT(without, 1e-3 * with) << with;
}

}  // namespace
}  // namespace lightlink::relight::testing
