// Emitter light per material: a change of emissive strengths or colours rescales the kept
// layers instead of sampling again, and gives exactly what a fresh relight of that light set
// gives (the sampling does not depend on the factors).
#include <gtest/gtest.h>

#include "core/relight/emitter_layers.h"
#include "tests/relight/relight_fixture.h"

namespace lightlink::relight {
namespace {

using namespace lightlink::relight::testing;

struct TwoLamps {
  std::unique_ptr<Baked> baked;
  int floor = -1, lamp_a = -1, lamp_b = -1;
};

// A floor, a wall and two downward lamps of different materials; the wall shadows part of
// the floor from lamp b.
TwoLamps twoLamps() {
  TwoLamps t;
  scene::Scene s;
  t.floor = addMaterial(s, glm::vec3(0.6f));
  t.lamp_a = addMaterial(s, glm::vec3(0.0f), glm::vec3(2.0f, 1.5f, 1.0f));
  t.lamp_b = addMaterial(s, glm::vec3(0.0f), glm::vec3(0.5f, 1.0f, 3.0f));
  addQuad(s, {-2, 0, -2}, {-2, 0, 2}, {2, 0, 2}, {2, 0, -2}, t.floor);
  addQuad(s, {-1.5f, 1, -0.25f}, {-1.0f, 1, -0.25f}, {-1.0f, 1, 0.25f}, {-1.5f, 1, 0.25f}, t.lamp_a);
  addQuad(s, {1.0f, 1, -0.25f}, {1.5f, 1, -0.25f}, {1.5f, 1, 0.25f}, {1.0f, 1, 0.25f}, t.lamp_b);
  addQuad(s, {0.5f, 0, -2}, {0.5f, 0.8f, -2}, {0.5f, 0.8f, 2}, {0.5f, 0, 2}, t.floor);
  auto o = smallOptions();
  o.lightmap_resolution = 40;
  t.baked = Baked::make(std::move(s), o);
  return t;
}

LightSet scaled(int material_a, glm::vec3 a, int material_b, glm::vec3 b) {
  LightSet set;
  EXPECT_TRUE(set.setEmissive({material_a, EmissiveOverride::Mode::kScale, a}));
  EXPECT_TRUE(set.setEmissive({material_b, EmissiveOverride::Mode::kScale, b}));
  return set;
}

const RelightOptions kOptions{.max_bounces = 1, .emitter_samples = 16};

TEST(EmitterLayers, StrengthAndColourChangesRescaleAndEqualAFreshRelight) {
  TwoLamps t = twoLamps();
  ASSERT_TRUE(t.baked);
  Relighter r = t.baked->relighter();
  auto first = r.relight(LightSet{}, kOptions);
  ASSERT_TRUE(first) << first.status().toString();
  EXPECT_EQ(first->passes.emissive_direct, 1);
  EXPECT_EQ(first->counts.emitter_rescaled, 0u);

  const LightSet dimmed = scaled(t.lamp_a, glm::vec3(0.25f, 0.5f, 2.0f), t.lamp_b, glm::vec3(3.0f));
  auto rescaled = r.relight(dimmed, kOptions);
  ASSERT_TRUE(rescaled) << rescaled.status().toString();
  EXPECT_EQ(rescaled->passes.emissive_direct, 0);
  EXPECT_EQ(rescaled->passes.surfel_emitter, 0);
  EXPECT_GE(rescaled->counts.emitter_rescaled, 2u);  // surfels and texels (and the grid when there is one)
  EXPECT_LT(rescaled->counts.shadow_rays, first->counts.shadow_rays);

  Relighter fresh_r = t.baked->relighter();
  auto fresh = fresh_r.relight(dimmed, kOptions);
  ASSERT_TRUE(fresh);
  EXPECT_EQ(fresh->passes.emissive_direct, 1);
  EXPECT_EQ(rescaled->direct, fresh->direct);
  EXPECT_EQ(rescaled->lightmap_sh, fresh->lightmap_sh);
  EXPECT_EQ(rescaled->grid_sh, fresh->grid_sh);
  EXPECT_NE(rescaled->direct, first->direct);
}

TEST(EmitterLayers, EachMaterialsLightGoesToItsOwnLayer) {
  // The light of both lamps is the sum of each lamp's alone, and a factor scales its lamp's
  // share only: a sample credited to the wrong material would break both.
  TwoLamps t = twoLamps();
  ASSERT_TRUE(t.baked);
  Relighter r = t.baked->relighter();
  const RelightOptions o{.max_bounces = 0, .emitter_samples = 16};
  auto both = r.relight(LightSet{}, o);
  auto only_a = r.relight(scaled(t.lamp_a, glm::vec3(1.0f), t.lamp_b, glm::vec3(0.0f)), o);
  auto only_b = r.relight(scaled(t.lamp_a, glm::vec3(0.0f), t.lamp_b, glm::vec3(1.0f)), o);
  auto a_times_4 = r.relight(scaled(t.lamp_a, glm::vec3(4.0f), t.lamp_b, glm::vec3(1.0f)), o);
  ASSERT_TRUE(both && only_a && only_b && a_times_4);
  double a_energy = 0.0, b_energy = 0.0;
  for (std::size_t i = 0; i < both->direct.size(); ++i) {
    const glm::vec3 sum = only_a->direct[i] + only_b->direct[i];
    const glm::vec3 four = 4.0f * only_a->direct[i] + only_b->direct[i];
    for (int ch = 0; ch < 3; ++ch) {
      EXPECT_NEAR(both->direct[i][ch], sum[ch], 1e-5f * (1.0f + sum[ch])) << "texel " << i;
      EXPECT_NEAR(a_times_4->direct[i][ch], four[ch], 1e-5f * (1.0f + four[ch])) << "texel " << i;
    }
    a_energy += only_a->direct[i].x, b_energy += only_b->direct[i].z;
  }
  EXPECT_GT(a_energy, 0.0);
  EXPECT_GT(b_energy, 0.0);
}

TEST(EmitterLayers, ANewEmitterOrAConstantRadianceSamplesAgain) {
  TwoLamps t = twoLamps();
  ASSERT_TRUE(t.baked);
  Relighter r = t.baked->relighter();
  ASSERT_TRUE(r.relight(LightSet{}, kOptions));
  LightSet glowing_floor;
  ASSERT_TRUE(glowing_floor.setEmissive({t.floor, EmissiveOverride::Mode::kRadiance, glm::vec3(0.1f)}));
  auto res = r.relight(glowing_floor, kOptions);
  ASSERT_TRUE(res);
  EXPECT_EQ(res->passes.emissive_direct, 1);
  EXPECT_EQ(res->counts.emitter_rescaled, 0u);
  // Another radiance for the same material keeps the layout: rescaled.
  LightSet brighter;
  ASSERT_TRUE(brighter.setEmissive({t.floor, EmissiveOverride::Mode::kRadiance, glm::vec3(0.3f)}));
  auto again = r.relight(brighter, kOptions);
  ASSERT_TRUE(again);
  EXPECT_EQ(again->passes.emissive_direct, 0);
  EXPECT_GE(again->counts.emitter_rescaled, 2u);
}

TEST(EmitterLayers, LayersBeyondTheBudgetSampleTheRealEmission) {
  TwoLamps t = twoLamps();
  ASSERT_TRUE(t.baked);
  const auto& scene = t.baked->scene;
  const std::vector<EmissiveOverride> dim{{t.lamp_a, EmissiveOverride::Mode::kScale, glm::vec3(0.5f)}};
  const auto small = detail::EmitterLayout::of(scene, dim, 1024);
  EXPECT_TRUE(small.layered());
  EXPECT_EQ(small.layers, 2);
  EXPECT_TRUE(small.sampled.empty());  // kScale is a factor, not sampled
  const auto f = small.factors(dim);
  ASSERT_EQ(f.size(), 2u);
  EXPECT_EQ(f[std::size_t(small.layer_of_material[t.lamp_a])], glm::vec3(0.5f));
  EXPECT_EQ(f[std::size_t(small.layer_of_material[t.lamp_b])], glm::vec3(1.0f));
  const auto big = detail::EmitterLayout::of(scene, dim, detail::kEmitterLayerBudgetBytes);
  EXPECT_FALSE(big.layered());
  EXPECT_EQ(big.layers, 1);
  ASSERT_EQ(big.sampled.size(), 1u);  // the real overrides: every change samples again
  EXPECT_EQ(big.sampled[0].value, glm::vec3(0.5f));
}

}  // namespace
}  // namespace lightlink::relight
