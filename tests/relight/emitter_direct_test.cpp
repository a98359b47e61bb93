// Emitter direct light: emissive surfaces sampled into the lightmap's `direct` output with
// soft shadows, and left out of the indirect SH (docs/relight.md "Direct vs indirect").
#include <cmath>
#include <cstring>
#include <numbers>

#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include "core/sh/sh.h"
#include "tests/relight/relight_fixture.h"

namespace lightlink::relight {
namespace {

using namespace lightlink::relight::testing;
constexpr float kPi = std::numbers::pi_v<float>;

// Emitter: a 0.5 m square at height 1 m facing down, radiance kLe; floor 4 m x 4 m at y = 0.
constexpr float kLe = 2.0f;
constexpr float kHalf = 0.25f;
constexpr float kHeight = 1.0f;
const glm::vec3 kEmitter[4] = {{-kHalf, kHeight, -kHalf}, {kHalf, kHeight, -kHalf}, {kHalf, kHeight, kHalf},
                               {-kHalf, kHeight, kHalf}};

// Irradiance at p (normal n) from a uniform Lambertian polygon of radiance L, fully above p's
// horizon (Lambert's formula): E = L / 2 * sum_i angle_i * dot(n, normalize(v_i x v_i+1)).
double polygonIrradiance(glm::dvec3 p, glm::dvec3 n, const glm::vec3* poly, int count, double radiance) {
  double sum = 0.0;
  for (int i = 0; i < count; ++i) {
    const glm::dvec3 a = glm::normalize(glm::dvec3(poly[i]) - p);
    const glm::dvec3 b = glm::normalize(glm::dvec3(poly[(i + 1) % count]) - p);
    const double angle = std::acos(std::clamp(glm::dot(a, b), -1.0, 1.0));
    sum += angle * glm::dot(n, glm::normalize(glm::cross(a, b)));
  }
  return 0.5 * radiance * std::abs(sum);
}

// blocker_half > 0 adds an opaque, double-sided square of that half size at y = 0.5.
std::unique_ptr<Baked> emitterOverFloor(float blocker_half, float floor_albedo = 0.0f) {
  scene::Scene s;
  const int floor = addMaterial(s, glm::vec3(floor_albedo));
  const int lamp = addMaterial(s, glm::vec3(0.0f), glm::vec3(kLe));
  addQuad(s, {-2, 0, -2}, {-2, 0, 2}, {2, 0, 2}, {2, 0, -2}, floor);  // faces +y
  addQuad(s, kEmitter[0], kEmitter[1], kEmitter[2], kEmitter[3], lamp);   // faces -y
  if (blocker_half > 0.0f) {
    const int blocker = addMaterial(s, glm::vec3(0.0f));
    s.materials[blocker].double_sided = true;
    const float h = blocker_half;
    addQuad(s, {-h, 0.5f, -h}, {-h, 0.5f, h}, {h, 0.5f, h}, {h, 0.5f, -h}, blocker);
  }
  auto o = smallOptions();
  o.lightmap_resolution = 48;
  return Baked::make(std::move(s), o);
}

bool onFloor(const caches::LightmapCaches& lm, std::size_t c) {
  return lm.valid[c] && lm.normal[c].y > 0.99f && lm.position[c].y < 0.01f;
}

TEST(EmitterDirect, MatchesLambertPolygonIrradianceAndStaysOutOfTheSh) {
  auto baked = emitterOverFloor(0.0f);
  ASSERT_TRUE(baked);
  Relighter r = baked->relighter();
  auto res = r.relight(LightSet{}, {.max_bounces = 0, .emitter_samples = 256});
  ASSERT_TRUE(res) << res.status().toString();
  EXPECT_EQ(res->passes.emissive_direct, 1);
  EXPECT_EQ(res->counts.emitter_triangles, 2u);
  const auto& lm = baked->p.lightmap;
  const int nc = res->coeffCount();
  int checked = 0;
  double abs_rel = 0.0;
  for (std::size_t c = 0; c < lm.size(); ++c) {
    if (!onFloor(lm, c) || std::abs(lm.position[c].x) > 1.5f || std::abs(lm.position[c].z) > 1.5f) continue;
    const double expected = polygonIrradiance(lm.position[c], lm.normal[c], kEmitter, 4, kLe);
    const glm::vec3 got = res->direct[lm.texel[c]];
    // 256 stratified solid-angle samples: measured 0.24 % worst texel, 0.04 % mean; the
    // bounds leave a 4-5x margin and still catch a wrong pdf or a lost cosine (> 10 %).
    EXPECT_NEAR(got.x, expected, 0.01 * expected) << "cache " << c << " at " << lm.position[c].x << ","
                                                  << lm.position[c].z;
    EXPECT_EQ(got.x, got.z);
    abs_rel += std::abs(got.x - expected) / expected;
    ++checked;
    // Black floor and lamp: nothing is reflected, so the indirect SH holds nothing, although
    // the links see the lamp (its direct light is in `direct` only).
    const float* t = res->lightmap_sh.data() + std::size_t(lm.texel[c]) * 3 * nc;
    ASSERT_EQ(sh::irradiance(res->bands, t, lm.normal[c]), 0.0f) << "cache " << c;
  }
  ASSERT_GT(checked, 200);
  EXPECT_LT(abs_rel / checked, 0.002);
}

// A weak lamp over the floor and, above it, a panel 400x brighter whose emitting side faces
// away (up): it cannot light the floor at all. Picking emitters by power alone would spend
// ~99.8 % of every floor texel's samples on the panel, leaving most texels with no sample on
// the lamp (black, or one sample x the 1/P weight: 100 % error). Picking per receiver gives
// the panel weight 0 for floor texels, so 8 samples all land on the lamp.
TEST(EmitterDirect, ReceiversDoNotSpendSamplesOnEmittersThatCannotLightThem) {
  scene::Scene s;
  const int floor = addMaterial(s, glm::vec3(0.0f));
  const int lamp = addMaterial(s, glm::vec3(0.0f), glm::vec3(kLe));
  const int panel = addMaterial(s, glm::vec3(0.0f), glm::vec3(400.0f * kLe));
  addQuad(s, {-2, 0, -2}, {-2, 0, 2}, {2, 0, 2}, {2, 0, -2}, floor);  // faces +y
  addQuad(s, kEmitter[0], kEmitter[1], kEmitter[2], kEmitter[3], lamp);   // faces -y
  addQuad(s, {-0.5f, 1.5f, -0.5f}, {-0.5f, 1.5f, 0.5f}, {0.5f, 1.5f, 0.5f}, {0.5f, 1.5f, -0.5f}, panel);  // faces +y
  auto o = smallOptions();
  o.lightmap_resolution = 48;
  auto baked = Baked::make(std::move(s), o);
  ASSERT_TRUE(baked);
  Relighter r = baked->relighter();
  auto res = r.relight(LightSet{}, {.max_bounces = 0, .emitter_samples = 8});
  ASSERT_TRUE(res) << res.status().toString();
  EXPECT_EQ(res->counts.emitter_triangles, 4u);
  const auto& lm = baked->p.lightmap;
  int checked = 0;
  double abs_rel = 0.0, worst = 0.0;
  for (std::size_t c = 0; c < lm.size(); ++c) {
    if (!onFloor(lm, c) || std::abs(lm.position[c].x) > 1.0f || std::abs(lm.position[c].z) > 1.0f) continue;
    const double expected = polygonIrradiance(lm.position[c], lm.normal[c], kEmitter, 4, kLe);
    const double err = std::abs(res->direct[lm.texel[c]].x - expected) / expected;
    abs_rel += err, worst = std::max(worst, err);
    ++checked;
  }
  ASSERT_GT(checked, 100);
  // 8 stratified solid-angle samples of the lamp alone: measured 1.2 % mean, 3.6 % worst
  // (picking by power: 265 % mean, 237x worst).
  EXPECT_LT(abs_rel / checked, 0.05);
  EXPECT_LT(worst, 0.25);
}

TEST(EmitterDirect, BlockerCastsASoftShadow) {
  constexpr float kBlocker = 0.2f;  // half size, at y = 0.5: half way to the emitter
  auto baked = emitterOverFloor(kBlocker);
  ASSERT_TRUE(baked);
  Relighter r = baked->relighter();
  auto res = r.relight(LightSet{}, {.max_bounces = 0, .emitter_samples = 64});
  ASSERT_TRUE(res) << res.status().toString();
  const auto& lm = baked->p.lightmap;
  // A floor point p sees the emitter through the plane y = 0.5 at (p + q) / 2, q on the
  // emitter: per axis the blocker hides all of it when |p| + 0.25 <= 2 * 0.2 (umbra,
  // |p| <= 0.15) and none of it when |p| - 0.25 >= 0.4 (|p| >= 0.65, unoccluded).
  int umbra = 0, penumbra = 0, lit = 0;
  for (std::size_t c = 0; c < lm.size(); ++c) {
    if (!onFloor(lm, c)) continue;
    const glm::vec3 p = lm.position[c];
    const float m = std::max(std::abs(p.x), std::abs(p.z));
    const double unoccluded = polygonIrradiance(p, lm.normal[c], kEmitter, 4, kLe);
    const float got = res->direct[lm.texel[c]].x;
    if (m < 0.12f) {
      EXPECT_EQ(got, 0.0f) << "umbra cache " << c << " at " << p.x << "," << p.z;
      ++umbra;
    } else if (m > 0.25f && m < 0.55f) {
      EXPECT_GT(got, 0.02 * unoccluded) << "penumbra cache " << c << " at " << p.x << "," << p.z;
      EXPECT_LT(got, 0.98 * unoccluded) << "penumbra cache " << c << " at " << p.x << "," << p.z;
      ++penumbra;
    } else if (m > 0.7f && m < 1.5f) {
      EXPECT_NEAR(got, unoccluded, 0.02 * unoccluded) << "lit cache " << c;
      ++lit;
    }
  }
  EXPECT_GT(umbra, 2);
  EXPECT_GT(penumbra, 20);
  EXPECT_GT(lit, 100);
}

// Closed box, every wall emitting L and reflecting rho: irradiance everywhere converges to
// E0 / (1 - rho), E0 = pi L. Direct carries E0 (every direction sees an emitter), indirect
// the reflected rest rho E0 / (1 - rho): the sum is right only if neither counts the other.
TEST(EmitterDirect, DirectPlusIndirectIsNotDoubleCountedInAFurnace) {
  constexpr float kRho = 0.5f, kEmit = 1.0f;
  scene::Scene s;
  const int m = addMaterial(s, glm::vec3(kRho), glm::vec3(kEmit));
  addBox(s, {0, 0, 0}, {2, 2, 2}, /*inward=*/true, m);
  auto baked = Baked::make(std::move(s), smallOptions());
  ASSERT_TRUE(baked);
  Relighter r = baked->relighter();
  auto res = r.relight(LightSet{}, {.max_bounces = 40, .bounce_threshold = 1e-4f, .emitter_samples = 64});
  ASSERT_TRUE(res) << res.status().toString();
  EXPECT_EQ(res->bounce_stop, "threshold");
  EXPECT_EQ(res->passes.surfel_emitter, 1);
  const double e0 = kPi * kEmit, expected = e0 / (1.0 - kRho);
  const auto& lm = baked->p.lightmap;
  const int nc = res->coeffCount();
  double direct = 0.0, indirect = 0.0;
  int n = 0;
  for (std::size_t c = 0; c < lm.size(); ++c) {
    if (!lm.valid[c]) continue;
    direct += res->direct[lm.texel[c]].x;
    indirect += sh::irradiance(res->bands, res->lightmap_sh.data() + std::size_t(lm.texel[c]) * 3 * nc, lm.normal[c]);
    ++n;
  }
  ASSERT_GT(n, 100);
  direct /= n, indirect /= n;
  EXPECT_NEAR(direct, e0, 0.02 * e0);
  EXPECT_NEAR(indirect, expected - e0, 0.02 * (expected - e0));
  EXPECT_NEAR(direct + indirect, expected, 0.015 * expected) << "direct " << direct << " indirect " << indirect;

  // Emitters not baked: the engine draws their direct light; the lightmap keeps the bounces.
  LightSet realtime;
  ASSERT_TRUE(realtime.setEmissiveBaked(false));
  auto rt_res = r.relight(realtime, {.max_bounces = 40, .bounce_threshold = 1e-4f, .emitter_samples = 64});
  ASSERT_TRUE(rt_res);
  EXPECT_FALSE(rt_res->plan.emissive_direct);
  EXPECT_EQ(rt_res->passes.emissive_direct, 0);
  for (const auto& d : rt_res->direct) ASSERT_EQ(d, glm::vec3(0.0f));
  EXPECT_EQ(rt_res->lightmap_sh, res->lightmap_sh);
}

TEST(EmitterDirect, OneAndTwoThreadsAreBitIdentical) {
  auto baked = emitterOverFloor(0.2f, /*floor_albedo=*/0.5f);
  ASSERT_TRUE(baked);
  auto run = [&](int threads) {
    tbb::global_control limit(tbb::global_control::max_allowed_parallelism, threads);
    Relighter r = baked->relighter();
    auto res = r.relight(LightSet{}, {.max_bounces = 2, .emitter_samples = 16});
    EXPECT_TRUE(res);
    return std::move(res).value();
  };
  const RelightResult one = run(1), two = run(2);
  EXPECT_GT(one.counts.shadow_rays, 0u);
  ASSERT_EQ(one.direct.size(), two.direct.size());
  EXPECT_EQ(0, std::memcmp(one.direct.data(), two.direct.data(), one.direct.size() * sizeof(glm::vec3)));
  ASSERT_EQ(one.lightmap_sh.size(), two.lightmap_sh.size());
  EXPECT_EQ(0, std::memcmp(one.lightmap_sh.data(), two.lightmap_sh.data(), one.lightmap_sh.size() * sizeof(float)));
  EXPECT_EQ(one.counts.shadow_rays, two.counts.shadow_rays);
}

TEST(EmitterDirect, PlanRunsThePassOnlyWhenSomethingEmitsAndIsBaked) {
  auto baked = emitterOverFloor(0.0f);
  ASSERT_TRUE(baked);
  Relighter r = baked->relighter();
  const RelightOptions o{.max_bounces = 0, .emitter_samples = 4};
  auto on = r.relight(LightSet{}, o);
  ASSERT_TRUE(on);
  EXPECT_TRUE(on->plan.emissive_direct);
  EXPECT_EQ(on->passes.emissive_direct, 1);
  EXPECT_NE(on->plan.toText().find("emitter direct"), std::string::npos);

  // Emission unchanged, a punctual light added, full (not incremental) relight: the emitter
  // direct of the last relight is reused (no emitter ray), and equals a fresh relighter's.
  LightSet lamp;
  LightEntry point;
  point.id = "p";
  point.light.position = {1, 0.5f, 1};
  ASSERT_TRUE(lamp.add(point));
  RelightOptions full_o = o;
  full_o.incremental = false;
  auto reused = r.relight(lamp, full_o);
  Relighter fresh = baked->relighter();
  auto full = fresh.relight(lamp, full_o);
  ASSERT_TRUE(reused && full);
  EXPECT_EQ(reused->passes.emissive_direct, 0);
  EXPECT_EQ(reused->counts.emitter_direct_reused, 1u);
  EXPECT_EQ(full->passes.emissive_direct, 1);
  EXPECT_EQ(reused->counts.emitter_triangles, 2u);
  EXPECT_LT(reused->counts.shadow_rays, full->counts.shadow_rays);
  EXPECT_EQ(reused->direct, full->direct);
  r.invalidate();
  auto again = r.relight(lamp, full_o);
  ASSERT_TRUE(again);
  EXPECT_EQ(again->passes.emissive_direct, 1);

  // Lamp switched off by an override: nothing emits, the pass does not run, no shadow ray.
  LightSet off;
  ASSERT_TRUE(off.setEmissive({.material = 1, .mode = EmissiveOverride::Mode::kRadiance, .value = glm::vec3(0.0f)}));
  auto dark = r.relight(off, o);
  ASSERT_TRUE(dark);
  EXPECT_FALSE(dark->plan.emissive_direct);
  EXPECT_EQ(dark->passes.emissive_direct, 0);
  EXPECT_EQ(dark->counts.shadow_rays, 0u);
  EXPECT_EQ(dark->counts.emitter_triangles, 0u);
  EXPECT_NE(dark->plan.toText().find("no emitting triangle"), std::string::npos);

  // A radiance override makes the floor an emitter: both quads are sampled.
  LightSet floor_glows;
  ASSERT_TRUE(floor_glows.setEmissive(
      {.material = 0, .mode = EmissiveOverride::Mode::kRadiance, .value = glm::vec3(1.0f)}));
  auto glow = r.relight(floor_glows, o);
  ASSERT_TRUE(glow);
  EXPECT_EQ(glow->passes.emissive_direct, 1);
  EXPECT_EQ(glow->counts.emitter_triangles, 4u);

  // Emitters left to the engine: skipped, and the plan says why.
  LightSet realtime;
  ASSERT_TRUE(realtime.setEmissiveBaked(false));
  auto rt_res = r.relight(realtime, o);
  ASSERT_TRUE(rt_res);
  EXPECT_EQ(rt_res->passes.emissive_direct, 0);
  EXPECT_NE(rt_res->plan.toText().find("emissive_baked = false"), std::string::npos);

  EXPECT_FALSE(r.relight(LightSet{}, {.emitter_samples = 0}));
}

TEST(EmitterDirect, EmissiveBakedFlagInTheLightSetJson) {
  auto set = LightSet::fromJson(nlohmann::json::parse(R"({"version": 1, "emissive_baked": false})"));
  ASSERT_TRUE(set) << set.status().toString();
  EXPECT_FALSE(set->emissiveBaked());
  auto back = LightSet::fromJson(set->toJson());
  ASSERT_TRUE(back);
  EXPECT_FALSE(back->emissiveBaked());
  auto dflt = LightSet::fromJson(nlohmann::json::parse(R"({"version": 1})"));
  ASSERT_TRUE(dflt);
  EXPECT_TRUE(dflt->emissiveBaked());
  const auto before = set->version();
  ASSERT_TRUE(set->setEmissiveBaked(true));
  EXPECT_GT(set->version(), before);
  auto bad = LightSet::fromJson(nlohmann::json::parse(R"({"version": 1, "emissive_baked": 1})"));
  ASSERT_FALSE(bad);
  EXPECT_NE(bad.status().message().find("emissive_baked"), std::string::npos) << bad.status().message();
}

}  // namespace
}  // namespace lightlink::relight
