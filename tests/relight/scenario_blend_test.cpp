// Lighting scenarios: relighting the blend of two scenarios (core/lights/scenarios.h) gives the
// same blend of their relights, lightmap, direct layer and grid, which is what lets an engine
// blend baked scenarios texel by texel and the daemon blend them by name.
#include <algorithm>
#include <cmath>

#include <gtest/gtest.h>

#include "core/lights/scenarios.h"
#include "tests/relight/relight_fixture.h"

namespace lightlink::relight {
namespace {

using namespace lightlink::relight::testing;

LightEntry pointAt(const std::string& id, glm::vec3 p, float candela, glm::vec3 colour) {
  LightEntry e;
  e.id = id;
  e.light.kind = lights::Light::Kind::kPoint;
  e.light.position = p;
  e.light.intensity = candela;
  e.light.color = colour;
  return e;
}

// max |blend - (wa a + wb b)| over the max |value|: 0 for an exactly linear relight.
float linearityError(const std::vector<float>& blend, const std::vector<float>& a, const std::vector<float>& b,
                     float wa, float wb) {
  EXPECT_EQ(blend.size(), a.size());
  EXPECT_EQ(blend.size(), b.size());
  float err = 0.0f, scale = 0.0f;
  for (std::size_t i = 0; i < blend.size(); ++i) {
    const float want = wa * a[i] + wb * b[i];
    err = std::max(err, std::abs(blend[i] - want));
    scale = std::max(scale, std::abs(want));
  }
  EXPECT_GT(scale, 0.0f);
  return err / scale;
}

std::vector<float> flat(const std::vector<glm::vec3>& v) {
  std::vector<float> out;
  for (const glm::vec3& c : v) out.insert(out.end(), {c.x, c.y, c.z});
  return out;
}

TEST(ScenarioBlend, RelightingABlendGivesTheBlendOfTheRelights) {
  scene::Scene s;
  const int floor = addMaterial(s, glm::vec3(0.6f));
  const int lamp = addMaterial(s, glm::vec3(0.0f), glm::vec3(2.0f, 1.5f, 1.0f));
  addQuad(s, {-2, 0, -2}, {-2, 0, 2}, {2, 0, 2}, {2, 0, -2}, floor);
  addQuad(s, {0.5f, 0, -2}, {0.5f, 1.5f, -2}, {0.5f, 1.5f, 2}, {0.5f, 0, 2}, floor);
  addQuad(s, {-1.5f, 1, -0.25f}, {-1.0f, 1, -0.25f}, {-1.0f, 1, 0.25f}, {-1.5f, 1, 0.25f}, lamp);
  auto o = smallOptions();
  o.grid = precompute::GridMode::kOn;
  o.grid_resolution = 4;
  auto baked = Baked::make(std::move(s), o);
  ASSERT_TRUE(baked);

  // Day: a warm light left of the wall, the lamp off, a blue sky. Night: a light right of
  // the wall, the lamp at twice its strength, no sky.
  lights::Scenario day{"day", {}}, night{"night", {}};
  ASSERT_TRUE(day.lights.add(pointAt("key", {-1, 1.2f, 0.5f}, 3.0f, {1, 0.8f, 0.6f})));
  ASSERT_TRUE(day.lights.setEmissive({lamp, lights::EmissiveOverride::Mode::kScale, glm::vec3(0.0f)}));
  ASSERT_TRUE(day.lights.setSky({glm::vec3(0.2f, 0.3f, 0.6f), std::nullopt}));
  ASSERT_TRUE(night.lights.add(pointAt("key", {1.2f, 1.0f, -0.5f}, 1.0f, {0.6f, 0.7f, 1.0f})));
  ASSERT_TRUE(night.lights.setEmissive({lamp, lights::EmissiveOverride::Mode::kScale, glm::vec3(2.0f)}));
  const std::vector<lights::Scenario> scenarios{day, night};
  const float wa = 0.3f, wb = 0.7f;
  auto blend = lights::blendScenarios(scenarios, std::vector<lights::ScenarioWeight>{{"day", wa}, {"night", wb}},
                                      baked->scene.materialEmissions());
  ASSERT_TRUE(blend) << blend.status().toString();

  // A fixed number of bounces (no threshold stop), so all three relights do the same work.
  const RelightOptions opt{.max_bounces = 3, .bounce_threshold = 0.0f, .incremental = false, .emitter_samples = 16};
  Relighter r = baked->relighter();
  auto a = r.relight(day.lights, opt);
  auto b = r.relight(night.lights, opt);
  auto m = r.relight(*blend, opt);
  ASSERT_TRUE(a && b && m);
  const float lightmap = linearityError(m->lightmap_sh, a->lightmap_sh, b->lightmap_sh, wa, wb);
  const float direct = linearityError(flat(m->direct), flat(a->direct), flat(b->direct), wa, wb);
  const float grid = linearityError(m->grid_sh, a->grid_sh, b->grid_sh, wa, wb);
  EXPECT_LT(lightmap, 1e-4f);
  EXPECT_LT(direct, 1e-4f);
  EXPECT_LT(grid, 1e-4f);
  std::printf("blend vs blended relights (max error / max value): lightmap %.2e, direct %.2e, grid %.2e\n", lightmap,
              direct, grid);
  // The scenarios differ, so the check has something to see.
  EXPECT_GT(linearityError(a->lightmap_sh, b->lightmap_sh, b->lightmap_sh, 0.5f, 0.5f), 0.1f);
}

}  // namespace
}  // namespace lightlink::relight
