// Lighting edge cases (DESIGN.md sec 6): albedo 1 in a closed room (bounces stop with a
// bound, never diverge), and scenes that give nothing to compute: no static geometry, no
// lights, lights of zero power. Each must give a clean, finite result whose effects plan
// says what was skipped.
#include <algorithm>
#include <cmath>

#include <gtest/gtest.h>

#include "tests/stability/stability_fixture.h"

namespace lightlink::stability {
namespace {

// ---- albedo 1 in a closed room ------------------------------------------------------------

TEST(StabilityBounces, AlbedoOneClosedRoomStopsAtTheCapWithBoundedEnergy) {
  // A white (rho = 1) closed room with a pillar, lit by one point light. No energy leaves,
  // so each bounce adds about as much flux as the one before: the series never converges
  // and the loop must stop at the cap, reporting "cap". Energy bound: the transport of one
  // bounce conserves flux at best (links see at most the hemisphere), so bounce k adds at
  // most what bounce k-1 added (+ 3 % for SH and sampling error), and after K bounces the
  // total flux is at most (K + 1) times the direct flux (+ the same margin).
  scene::Scene s;
  const int white = addMaterial(s, glm::vec3(1.0f));
  addBox(s, {0, 0, 0}, {3, 2, 2}, /*inward=*/true, white);
  addBox(s, {1.3f, 0.0f, 0.8f}, {1.7f, 2.0f, 1.2f}, /*inward=*/false, white);
  auto o = tinyOptions();
  o.grid = precompute::GridMode::kOn;
  auto baked = Baked::make(std::move(s), o);
  ASSERT_TRUE(baked);
  relight::Relighter r = baked->relighter();
  LightSet set;
  ASSERT_TRUE(set.add(pointLight("lamp", {0.5f, 1.5f, 1.0f}, 2.0f)));
  const int cap = 24;
  auto res = r.relight(set, {.max_bounces = cap, .bounce_threshold = 1e-3f});
  ASSERT_TRUE(res) << res.status().toString();
  EXPECT_EQ(countBadValues(*res, "albedo 1"), 0u);
  EXPECT_EQ(res->bounce_stop, "cap");
  ASSERT_EQ(int(res->bounce_log.size()), cap);
  EXPECT_EQ(res->plan.max_bounces, cap);

  double direct_flux = 0.0;  // flux of the direct light alone: rho E_direct A
  {
    auto first = r.relight(set, {.max_bounces = 0});
    ASSERT_TRUE(first);
    for (std::size_t i = 0; i < first->surfel_radiosity.size(); ++i)
      for (int ch = 0; ch < 3; ++ch)  // summed over channels, as the bounce log is
        direct_flux += double(first->surfel_radiosity[i][ch]) * baked->p.surfels.area[i];
  }
  ASSERT_GT(direct_flux, 0.0);
  double worst_growth = 0.0;
  for (std::size_t k = 1; k < res->bounce_log.size(); ++k)
    worst_growth = std::max(worst_growth, res->bounce_log[k].added_flux / res->bounce_log[k - 1].added_flux);
  std::printf("albedo 1: %d bounces, largest bounce-to-bounce ratio %.4f, final flux %.2f x direct (bound %d)\n", cap,
              worst_growth, res->bounce_log.back().total_flux / direct_flux, cap + 1);
  for (std::size_t k = 0; k < res->bounce_log.size(); ++k) {
    const auto& b = res->bounce_log[k];
    ASSERT_TRUE(std::isfinite(b.total_flux));
    EXPECT_LE(b.total_flux, 1.03 * double(k + 2) * direct_flux) << "bounce " << k + 1;
    if (k == 0) continue;
    EXPECT_LE(b.added_flux, 1.03 * res->bounce_log[k - 1].added_flux) << "bounce " << k + 1 << " grew";
    // ... and the room is closed: a bounce does not lose much either (>= 80 % passed on).
    EXPECT_GE(b.added_flux, 0.8 * res->bounce_log[k - 1].added_flux) << "bounce " << k + 1;
  }
  // Per surfel: radiosity below (cap + 1) times the largest direct radiosity (+ margin).
  auto first = r.relight(set, {.max_bounces = 0});
  ASSERT_TRUE(first);
  float direct_max = 0.0f;
  for (const auto& b : first->surfel_radiosity) direct_max = std::max(direct_max, b.x);
  for (std::size_t i = 0; i < res->surfel_radiosity.size(); ++i)
    ASSERT_LE(res->surfel_radiosity[i].x, 1.03f * float(cap + 1) * direct_max) << "surfel " << i;
}

// ---- nothing to compute --------------------------------------------------------------------

bool mentions(const relight::EffectsPlan& plan, const std::string& what) {
  for (const auto& r : plan.reasons)
    if (r.find(what) != std::string::npos) return true;
  return false;
}

void expectAllZero(const RelightResult& res, const std::string& what) {
  EXPECT_EQ(countBadValues(res, what), 0u);
  for (float v : res.lightmap_sh) ASSERT_EQ(v, 0.0f) << what;
  for (float v : res.grid_sh) ASSERT_EQ(v, 0.0f) << what;
  for (const auto& d : res.direct) ASSERT_EQ(d, glm::vec3(0.0f)) << what;
  for (const auto& b : res.surfel_radiosity) ASSERT_EQ(b, glm::vec3(0.0f)) << what;
}

struct LitRoom {
  std::unique_ptr<Baked> baked;
  LitRoom() {
    scene::Scene s;
    const int m = addMaterial(s, glm::vec3(0.5f));
    addBox(s, {0, 0, 0}, {2, 2, 2}, /*inward=*/true, m);
    auto o = tinyOptions();
    o.grid = precompute::GridMode::kOn;
    baked = Baked::make(std::move(s), o);
  }
};

TEST(StabilityEmpty, NoLightsGiveAZeroResultAndThePlanSaysSkipped) {
  static LitRoom room;
  ASSERT_TRUE(room.baked);
  relight::Relighter r = room.baked->relighter();
  auto res = r.relight(LightSet{}, {.max_bounces = 8});
  ASSERT_TRUE(res) << res.status().toString();
  expectAllZero(*res, "no lights");
  EXPECT_FALSE(res->plan.punctual);
  EXPECT_FALSE(res->plan.bounces);
  EXPECT_FALSE(res->plan.baked_direct);
  EXPECT_TRUE(mentions(res->plan, "skipped")) << res->plan.toText();
  EXPECT_EQ(res->passes.surfel_direct, 0);
  EXPECT_EQ(res->passes.bounces, 0);
  EXPECT_EQ(res->passes.baked_direct, 0);
  EXPECT_EQ(res->bounce_stop, "no light");
  EXPECT_TRUE(res->bounce_log.empty());
}

TEST(StabilityEmpty, ZeroPowerLightsAreSkippedLikeNoLights) {
  static LitRoom room;
  ASSERT_TRUE(room.baked);
  relight::Relighter r = room.baked->relighter();
  LightSet set;
  ASSERT_TRUE(set.add(pointLight("off", {1, 1, 1}, 0.0f)));
  ASSERT_TRUE(set.add(pointLight("black", {1, 1.5f, 1}, 50.0f, glm::vec3(0.0f))));
  LightEntry spot = pointLight("spot-off", {1, 1.9f, 1}, 0.0f);
  spot.light.kind = scene::Light::Kind::kSpot;
  spot.light.direction = {0, -1, 0};
  ASSERT_TRUE(set.add(spot));
  LightEntry sun = pointLight("sun-off", {0, 0, 0}, 0.0f);
  sun.light.kind = scene::Light::Kind::kDirectional;
  sun.light.direction = {0, -1, 0};
  ASSERT_TRUE(set.add(sun));
  ASSERT_TRUE(set.setSky({.radiance = glm::vec3(0.0f)}));
  auto res = r.relight(set, {.max_bounces = 8});
  ASSERT_TRUE(res) << res.status().toString();
  expectAllZero(*res, "zero-power lights");
  EXPECT_FALSE(res->plan.punctual) << res->plan.toText();
  EXPECT_FALSE(res->plan.sky);
  EXPECT_TRUE(mentions(res->plan, "no light with non-zero intensity")) << res->plan.toText();
  EXPECT_EQ(res->passes.surfel_direct, 0);
  EXPECT_EQ(res->passes.baked_direct, 0);
  EXPECT_EQ(res->counts.shadow_rays, 0u);
  // One light switched on afterwards lights the room: the zero result was not a stuck state.
  ASSERT_TRUE(set.modify(pointLight("off", {1, 1, 1}, 3.0f)));
  auto on = r.relight(set, {.max_bounces = 1});
  ASSERT_TRUE(on);
  EXPECT_TRUE(on->plan.punctual);
  EXPECT_GT(on->surfel_radiosity[0].x + on->surfel_radiosity.back().x, 0.0f);
}

TEST(StabilityEmpty, SceneWithoutStaticGeometryIsACleanErrorNamingWhatIsMissing) {
  // Nothing to bake: the loader rejects a glTF without triangles (tests/scene), and a scene
  // built in memory that reaches precompute with no static area (only a dynamic prop, or
  // nothing at all) must be an invalidInput that says so, not a crash, a division by the zero
  // area or an artifact full of NaN. (Measured behaviour: precompute refuses, it does not
  // produce an empty bake.)
  for (int variant = 0; variant < 2; ++variant) {
    scene::Scene s;
    s.source_path = variant == 0 ? "dynamic-only" : "nothing";
    if (variant == 0) {
      addBox(s, {0, 0, 0}, {1, 1, 1}, /*inward=*/false);
      for (auto& m : s.meshes) m.is_static = false;
    }
    lightlink::testing::finishScene(s);
    auto p = precompute::run(s, tinyOptions());
    ASSERT_FALSE(p) << s.source_path << ": a bake without static geometry should be refused";
    EXPECT_EQ(p.status().code(), Code::kInvalidInput) << p.status().toString();
    EXPECT_NE(p.status().message().find("static"), std::string::npos) << p.status().message();
    EXPECT_NE(p.status().message().find(s.source_path), std::string::npos) << p.status().message();
  }
}

}  // namespace
}  // namespace lightlink::stability
