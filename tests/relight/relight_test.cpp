#include "core/relight/relight.h"

#include <algorithm>
#include <cmath>
#include <numbers>

#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include "core/links/links.h"
#include "core/scene/light_eval.h"
#include "core/sh/sh.h"
#include "tests/common/testing.h"
#include "tests/relight/relight_fixture.h"

namespace lightlink::relight {
namespace {

using namespace lightlink::relight::testing;
constexpr float kPi = std::numbers::pi_v<float>;

// Irradiance at normal n from the R channel of one texel's / cache's SH (3 * nc floats).
float irradianceR(const float* sh_rgb, int bands, glm::vec3 n) { return sh::irradiance(bands, sh_rgb, n); }

LightEntry pointLight(std::string id, glm::vec3 pos, float intensity_cd, float range = 0.0f, bool baked = true) {
  LightEntry e;
  e.id = std::move(id);
  e.light.kind = scene::Light::Kind::kPoint;
  e.light.position = pos;
  e.light.intensity = intensity_cd;
  e.light.range = range;
  e.baked = baked;
  return e;
}

// ---- furnace: closed box, uniform emission and albedo --------------------------------

struct Furnace {
  static constexpr float kRho = 0.5f;
  static constexpr float kEmit = 1.0f;  // radiance
  std::unique_ptr<Baked> baked;
  Furnace() {
    scene::Scene s;
    const int m = addMaterial(s, glm::vec3(kRho), glm::vec3(kEmit));
    addBox(s, {0, 0, 0}, {2, 2, 2}, /*inward=*/true, m);
    auto o = smallOptions();
    o.grid = precompute::GridMode::kOn;
    o.grid_resolution = 3;
    baked = Baked::make(std::move(s), o);
  }
};

const Furnace& furnace() {
  static Furnace f;
  return f;
}

TEST(RelightFurnace, ConvergedRadiosityIsE0OverOneMinusRho) {
  const auto& f = furnace();
  ASSERT_TRUE(f.baked);
  Relighter r = f.baked->relighter();
  auto res = r.relight(LightSet{}, {.max_bounces = 40, .bounce_threshold = 1e-4f, .emitter_samples = 256});
  ASSERT_TRUE(res) << res.status().toString();
  const float e0 = kPi * Furnace::kEmit;
  const float expected = e0 / (1.0f - Furnace::kRho);
  double b_area = 0.0, area = 0.0;
  for (std::size_t s = 0; s < res->surfel_radiosity.size(); ++s) {
    b_area += double(res->surfel_radiosity[s].x) * f.baked->p.surfels.area[s];
    area += f.baked->p.surfels.area[s];
  }
  EXPECT_NEAR(b_area / area, expected, 0.01 * expected) << "bounces " << res->bounce_log.size();
  EXPECT_EQ(res->bounce_stop, "threshold");
  // Every wall texel sees radiosity B all around: irradiance B, the emitters' pi L sampled
  // into direct and the reflected rho B in the indirect SH.
  const auto& lm = f.baked->p.lightmap;
  const int nc = res->coeffCount();
  double sum = 0.0;
  int n = 0;
  for (std::size_t c = 0; c < lm.size(); ++c) {
    if (!lm.valid[c]) continue;
    const float e = res->direct[lm.texel[c]].x +
                    irradianceR(res->lightmap_sh.data() + std::size_t(lm.texel[c]) * 3 * nc, res->bands, lm.normal[c]);
    sum += e, ++n;
    // Texels half a texel from an edge see the adjacent wall as a near-field emitter; the
    // solid-angle sampling of the direct light keeps them within the same tolerance. A cache
    // pushed off its texel centre sits within its texel, 1/16 texel from the corner (issue
    // 46; it used to be moved to its triangle's centroid): there the links' indirect reads
    // 15-20 % low, 8-10 % of the total (a known limitation of links in concave corners).
    const double tolerance = lm.pushed[c] ? 0.12 : 0.06;
    EXPECT_NEAR(e, expected, tolerance * expected) << "cache " << c << " at " << lm.position[c].x << ","
                                               << lm.position[c].y << "," << lm.position[c].z << " direct "
                                               << res->direct[lm.texel[c]].x;
  }
  ASSERT_GT(n, 100);
  EXPECT_NEAR(sum / n, expected, 0.02 * expected);
  // Grid caches inside the box see uniform radiance B / pi over the whole sphere.
  ASSERT_TRUE(res->plan.grid);
  ASSERT_FALSE(res->grid_sh.empty());
  for (std::size_t g = 0; g < f.baked->p.grid.size(); ++g) {
    if (!f.baked->p.grid.valid[g]) continue;
    EXPECT_NEAR(res->grid_sh[g * 3 * nc], expected / kPi * 2.0f * std::sqrt(kPi), 0.03 * expected)
        << "grid cache " << g;
  }
}

TEST(RelightFurnace, BounceCountObeysThresholdAndCap) {
  const auto& f = furnace();
  ASSERT_TRUE(f.baked);
  Relighter r = f.baked->relighter();
  auto res = r.relight(LightSet{}, {.max_bounces = 40, .bounce_threshold = 1e-2f});
  ASSERT_TRUE(res);
  ASSERT_FALSE(res->bounce_log.empty());
  // Every bounce but the last added at least the threshold; the last added less.
  for (std::size_t k = 0; k + 1 < res->bounce_log.size(); ++k)
    EXPECT_GE(res->bounce_log[k].added_flux, 1e-2 * res->bounce_log[k].total_flux) << "bounce " << k + 1;
  EXPECT_LT(res->bounce_log.back().added_flux, 1e-2 * res->bounce_log.back().total_flux);
  EXPECT_EQ(res->bounce_stop, "threshold");
  // rho = 0.5: bounce k adds ~0.5^k of E0 relative to the total ~2 E0: 1 % is reached at k ~ 6.
  EXPECT_GE(res->bounce_log.size(), 4u);
  EXPECT_LE(res->bounce_log.size(), 9u);
  EXPECT_EQ(res->passes.bounces, int(res->bounce_log.size()));

  auto capped = r.relight(LightSet{}, {.max_bounces = 2, .bounce_threshold = 1e-6f});
  ASSERT_TRUE(capped);
  EXPECT_EQ(capped->bounce_log.size(), 2u);
  EXPECT_EQ(capped->bounce_stop, "cap");
  EXPECT_EQ(capped->passes.pulls, 3);  // direct + 2 bounces

  auto none = r.relight(LightSet{}, {.max_bounces = 0});
  ASSERT_TRUE(none);
  EXPECT_TRUE(none->bounce_log.empty());
  EXPECT_EQ(none->bounce_stop, "disabled");
  EXPECT_EQ(none->passes.bounces, 0);
}

TEST(RelightFurnace, AlbedoOneStopsAtTheCapWithABoundedResult) {
  // rho = 1 in a closed room never converges (each bounce adds ~E0): the loop must stop at
  // the cap with finite values bounded by (cap + 2) E0 (emission, its direct light at the
  // surfels, cap bounces), never diverge.
  scene::Scene s;
  const int m = addMaterial(s, glm::vec3(1.0f), glm::vec3(1.0f));
  addBox(s, {0, 0, 0}, {2, 2, 2}, /*inward=*/true, m);
  auto baked = Baked::make(std::move(s), smallOptions());
  ASSERT_TRUE(baked);
  Relighter r = baked->relighter();
  const int cap = 6;
  auto res = r.relight(LightSet{}, {.max_bounces = cap, .bounce_threshold = 1e-3f});
  ASSERT_TRUE(res);
  EXPECT_EQ(res->bounce_stop, "cap");
  EXPECT_EQ(int(res->bounce_log.size()), cap);
  const float e0 = kPi;
  for (const auto& b : res->surfel_radiosity) {
    ASSERT_TRUE(std::isfinite(b.x));
    ASSERT_LE(b.x, (cap + 2) * e0 * 1.1f);  // 10 %: the surfels' sampled emitter light is noisy
  }
  for (std::size_t k = 1; k < res->bounce_log.size(); ++k)
    EXPECT_NEAR(res->bounce_log[k].added_flux, res->bounce_log[0].added_flux, 0.1 * res->bounce_log[0].added_flux);
  // The default options run bounces to convergence; here the default cap is what ends them.
  auto by_default = r.relight(LightSet{}, {});
  ASSERT_TRUE(by_default);
  EXPECT_EQ(by_default->bounce_stop, "cap");
  EXPECT_EQ(int(by_default->bounce_log.size()), RelightOptions{}.max_bounces);
  EXPECT_LE(RelightOptions{}.max_bounces, 256);
}

TEST(RelightFurnace, FillAndDilationLeaveNoBlackTexelNextToAValidOne) {
  const auto& f = furnace();
  ASSERT_TRUE(f.baked);
  Relighter r = f.baked->relighter();
  // One bounce: the emitting walls' direct light and their reflection (indirect) both have
  // a value at every valid texel.
  auto res = r.relight(LightSet{}, {.max_bounces = 1});
  ASSERT_TRUE(res);
  const auto& lm = f.baked->p.lightmap;
  const int nc = res->coeffCount();
  const int w = res->width, h = res->height;
  std::size_t checked = 0;
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const std::size_t t = std::size_t(y) * w + x;
      bool neighbour_valid = lm.cache_of_texel[t] >= 0;
      for (int dy = -1; dy <= 1 && !neighbour_valid; ++dy)
        for (int dx = -1; dx <= 1; ++dx) {
          const int nx = x + dx, ny = y + dy;
          if (nx < 0 || ny < 0 || nx >= w || ny >= h) continue;
          const std::int32_t c = lm.cache_of_texel[std::size_t(ny) * w + nx];
          neighbour_valid |= c >= 0 && lm.valid[c];
        }
      if (!neighbour_valid) continue;
      ++checked;
      EXPECT_TRUE(res->texel_valid[t]) << "texel " << x << "," << y;
      EXPECT_GT(res->lightmap_sh[t * 3 * nc], 0.1f) << "black texel " << x << "," << y;
      EXPECT_GT(res->direct[t].x, 0.1f) << "no direct light at texel " << x << "," << y;
    }
  EXPECT_GT(checked, lm.size());  // the gutter texels were checked too
  EXPECT_EQ(res->passes.fill, 1);
}

// ---- point light over a plane: baked direct --------------------------------------------

TEST(RelightDirect, BakedDirectIrradianceIsIntensityCosOverDistanceSquared) {
  scene::Scene s;
  const int m = addMaterial(s, glm::vec3(0.5f));
  addQuad(s, {-2, 0, -2}, {-2, 0, 2}, {2, 0, 2}, {2, 0, -2}, m);   // floor facing +y
  addQuad(s, {-0.3f, 0.5f, -0.3f}, {0.3f, 0.5f, -0.3f}, {0.3f, 0.5f, 0.3f}, {-0.3f, 0.5f, 0.3f}, m);  // blocker
  auto baked = Baked::make(std::move(s), smallOptions());
  ASSERT_TRUE(baked);
  Relighter r = baked->relighter();
  LightSet set;
  const glm::vec3 light_pos(1.0f, 1.0f, 0.5f);
  ASSERT_TRUE(set.add(pointLight("lamp", light_pos, 10.0f)));
  auto res = r.relight(set, {.max_bounces = 0});
  ASSERT_TRUE(res) << res.status().toString();
  const auto& lm = baked->p.lightmap;
  int lit = 0, shadowed = 0;
  for (std::size_t c = 0; c < lm.size(); ++c) {
    if (!lm.valid[c] || lm.normal[c].y < 0.99f || lm.position[c].y > 0.01f) continue;  // floor top
    const glm::vec3 p = lm.position[c];
    const glm::vec3 d = light_pos - p;
    const float dist = glm::length(d);
    const float expected = 10.0f * (d.y / dist) / (dist * dist);
    // Does the segment to the light cross the blocker square at y = 0.5?
    const float t = (0.5f - p.y) / d.y;
    const glm::vec3 q = p + t * d;
    const bool blocked = std::abs(q.x) < 0.3f && std::abs(q.z) < 0.3f;
    const bool near_edge = std::abs(std::abs(q.x) - 0.3f) < 0.02f || std::abs(std::abs(q.z) - 0.3f) < 0.02f;
    if (near_edge) continue;
    const glm::vec3 got = res->direct[lm.texel[c]];
    if (blocked) {
      EXPECT_EQ(got.x, 0.0f) << "cache " << c << " should be in the blocker's shadow";
      ++shadowed;
    } else {
      EXPECT_NEAR(got.x, expected, 1e-4f * expected) << "cache " << c;
      EXPECT_EQ(got.x, got.y);
      ++lit;
    }
  }
  EXPECT_GT(lit, 100);
  EXPECT_GT(shadowed, 3);
  EXPECT_EQ(res->passes.baked_direct, 1);
}

// ---- effects plan ------------------------------------------------------------------------

TEST(RelightPlan, SkippedPassesDoNotRun) {
  scene::Scene s;
  const int m = addMaterial(s, glm::vec3(0.5f));
  addQuad(s, {-2, 0, -2}, {-2, 0, 2}, {2, 0, 2}, {2, 0, -2}, m);
  auto baked = Baked::make(std::move(s), smallOptions());
  ASSERT_TRUE(baked);
  ASSERT_FALSE(baked->p.has_grid);
  Relighter r = baked->relighter();
  LightSet set;
  ASSERT_TRUE(set.add(pointLight("realtime", {0, 1, 0}, 5.0f, 0.0f, /*baked=*/false)));
  auto res = r.relight(set, {.max_bounces = 2});
  ASSERT_TRUE(res);
  EXPECT_FALSE(res->plan.emissive);
  EXPECT_FALSE(res->plan.sky);
  EXPECT_FALSE(res->plan.grid);
  EXPECT_FALSE(res->plan.baked_direct);
  EXPECT_EQ(res->passes.emission, 0);
  EXPECT_EQ(res->passes.sky, 0);
  EXPECT_EQ(res->passes.grid_lighting, 0);
  EXPECT_EQ(res->passes.baked_direct, 0);
  EXPECT_EQ(res->passes.surfel_direct, 1);
  for (const auto& d : res->direct) ASSERT_EQ(d, glm::vec3(0.0f));  // realtime light: no baked direct
  EXPECT_NE(res->plan.toText().find("no baked light"), std::string::npos);

  // Turning each effect on makes its pass run.
  Sky sky;
  sky.radiance = glm::vec3(0.2f);
  ASSERT_TRUE(set.setSky(sky));
  ASSERT_TRUE(set.modify(pointLight("realtime", {0, 1, 0}, 5.0f, 0.0f, /*baked=*/true)));
  auto res2 = r.relight(set, {.max_bounces = 0});
  ASSERT_TRUE(res2);
  EXPECT_TRUE(res2->plan.sky);
  EXPECT_EQ(res2->passes.sky, 1);
  EXPECT_EQ(res2->passes.baked_direct, 1);
  EXPECT_EQ(res2->passes.bounces, 0);

  // No light at all: nothing is evaluated and the result is black.
  auto dark = r.relight(LightSet{}, {});
  ASSERT_TRUE(dark);
  EXPECT_EQ(dark->passes.surfel_direct, 0);
  EXPECT_EQ(dark->passes.bounces, 0);
  EXPECT_EQ(dark->bounce_stop, "no light");
  for (float v : dark->lightmap_sh) ASSERT_EQ(v, 0.0f);
}

TEST(RelightSky, UniformSkyOverAnOpenPlaneGivesPiL) {
  scene::Scene s;
  const int m = addMaterial(s, glm::vec3(0.0f));
  addQuad(s, {-2, 0, -2}, {-2, 0, 2}, {2, 0, 2}, {2, 0, -2}, m);
  auto baked = Baked::make(std::move(s), smallOptions());
  ASSERT_TRUE(baked);
  Relighter r = baked->relighter();
  std::vector<float> uniform_sh;
  for (bool as_sh : {false, true}) {
    LightSet set;
    Sky sky;
    sky.radiance = glm::vec3(0.7f, 0.3f, 0.1f);
    if (as_sh) {
      sky.sh = sky.radianceSh();
      sky.radiance = glm::vec3(0.0f);
    }
    ASSERT_TRUE(set.setSky(sky));
    auto res = r.relight(set, {.max_bounces = 0});
    ASSERT_TRUE(res);
    const auto& lm = baked->p.lightmap;
    const int nc = res->coeffCount();
    double mean = 0.0;
    int n = 0;
    for (std::size_t c = 0; c < lm.size(); ++c) {
      if (!lm.valid[c]) continue;
      const float* t = res->lightmap_sh.data() + std::size_t(lm.texel[c]) * 3 * nc;
      // 256 stratified link rays: the sky visibility's band 1 carries ~1 % Monte Carlo noise.
      const float e = sh::irradiance(res->bands, t, lm.normal[c]);
      EXPECT_NEAR(e, kPi * 0.7f, 0.02f * kPi * 0.7f) << "cache " << c;
      EXPECT_NEAR(sh::irradiance(res->bands, t + 2 * nc, lm.normal[c]), kPi * 0.1f, 0.02f * kPi * 0.1f);
      mean += e, ++n;
    }
    ASSERT_GT(n, 100);
    EXPECT_NEAR(mean / n, kPi * 0.7f, 0.002f * kPi * 0.7f);
    // The SH sky of a constant is the uniform sky: the product matrix is exact.
    if (!as_sh) {
      uniform_sh = res->lightmap_sh;
    } else {
      ASSERT_EQ(uniform_sh.size(), res->lightmap_sh.size());
      for (std::size_t i = 0; i < uniform_sh.size(); ++i) ASSERT_NEAR(uniform_sh[i], res->lightmap_sh[i], 1e-5f) << i;
    }
  }
}

// ---- incremental ---------------------------------------------------------------------------

struct Room {
  std::unique_ptr<Baked> baked;
  Room() {
    scene::Scene s;
    const int m = addMaterial(s, glm::vec3(0.6f, 0.5f, 0.4f));
    const int e = addMaterial(s, glm::vec3(0.5f), glm::vec3(2.0f));
    addBox(s, {0, 0, 0}, {6, 2, 2}, /*inward=*/true, m);
    addQuad(s, {2.9f, 1.99f, 0.9f}, {3.1f, 1.99f, 0.9f}, {3.1f, 1.99f, 1.1f}, {2.9f, 1.99f, 1.1f}, e);  // ceiling lamp
    auto o = smallOptions();
    o.grid = precompute::GridMode::kOn;
    o.grid_resolution = 4;
    baked = Baked::make(std::move(s), o);
  }
};

const Room& room() {
  static Room r;
  return r;
}

void expectSame(const RelightResult& a, const RelightResult& b, const char* what) {
  ASSERT_EQ(a.lightmap_sh.size(), b.lightmap_sh.size());
  std::size_t diff = 0;
  for (std::size_t i = 0; i < a.lightmap_sh.size(); ++i)
    diff += std::abs(a.lightmap_sh[i] - b.lightmap_sh[i]) > 1e-6f * (1.0f + std::abs(b.lightmap_sh[i]));
  EXPECT_EQ(diff, 0u) << what << ": lightmap SH differs";
  diff = 0;
  for (std::size_t i = 0; i < a.direct.size(); ++i)
    diff += glm::any(glm::greaterThan(glm::abs(a.direct[i] - b.direct[i]), 1e-6f * (1.0f + glm::abs(b.direct[i]))));
  EXPECT_EQ(diff, 0u) << what << ": direct differs";
  ASSERT_EQ(a.grid_sh.size(), b.grid_sh.size());
  diff = 0;
  for (std::size_t i = 0; i < a.grid_sh.size(); ++i)
    diff += std::abs(a.grid_sh[i] - b.grid_sh[i]) > 1e-6f * (1.0f + std::abs(b.grid_sh[i]));
  EXPECT_EQ(diff, 0u) << what << ": grid SH differs";
}

// Two ranged lamps at the room's ends, one of them realtime (not baked).
LightSet roomLamps() {
  LightSet set;
  EXPECT_TRUE(set.add(pointLight("a", {1, 1, 1}, 3.0f, 1.5f)));
  EXPECT_TRUE(set.add(pointLight("b", {5, 1, 1}, 2.0f, 1.5f, /*baked=*/false)));
  return set;
}

TEST(RelightIncremental, OneLightChangeMatchesAFullRelight) {
  const auto& rm = room();
  ASSERT_TRUE(rm.baked);
  Relighter inc = rm.baked->relighter();
  LightSet set = roomLamps();
  const RelightOptions opt{.max_bounces = 0};
  auto first = inc.relight(set, opt);
  ASSERT_TRUE(first);
  EXPECT_EQ(first->passes.incremental, 0);

  auto check = [&](const char* what) -> RelightResult {
    auto r = inc.relight(set, opt);
    EXPECT_TRUE(r);
    if (!r) return {};
    EXPECT_EQ(r->passes.incremental, 1) << what;
    Relighter fresh = rm.baked->relighter();
    auto full = fresh.relight(set, opt);
    EXPECT_TRUE(full);
    if (!full) return {};
    EXPECT_EQ(full->passes.incremental, 0);
    expectSame(*r, *full, what);
    return std::move(r).value();
  };
  // Move light a within its range: only surfels within 1.5 m of either position are re-lit.
  ASSERT_TRUE(set.modify(pointLight("a", {1.5f, 1, 1}, 3.0f, 1.5f)));
  const RelightResult moved = check("move");
  EXPECT_GT(moved.counts.surfels_lit, 0u);
  EXPECT_LT(moved.counts.surfels_lit, moved.counts.surfels / 2);
  EXPECT_LT(moved.counts.nodes_pulled, moved.counts.nodes);
  EXPECT_LE(moved.counts.caches_summed, moved.counts.caches);
  // Add, then remove, a third light.
  ASSERT_TRUE(set.add(pointLight("c", {3, 1, 1.5f}, 1.0f, 1.0f)));
  check("add");
  ASSERT_TRUE(set.remove("b"));
  check("remove");
  // Flip a light to realtime: only baked direct changes.
  ASSERT_TRUE(set.modify(pointLight("c", {3, 1, 1.5f}, 1.0f, 1.0f, /*baked=*/false)));
  const RelightResult flipped = check("baked flag");
  EXPECT_EQ(flipped.counts.surfels_lit, 0u);
  // A spot light (cone reach) and a directional light (reaches every surfel).
  LightEntry spot = pointLight("spot", {4, 1.9f, 1}, 20.0f);
  spot.light.kind = scene::Light::Kind::kSpot;
  spot.light.direction = {0, -1, 0};
  spot.light.outer_cone_angle = 0.4f;
  ASSERT_TRUE(set.add(spot));
  const RelightResult spot_added = check("spot");
  EXPECT_LT(spot_added.counts.surfels_lit, spot_added.counts.surfels / 4);
  LightEntry sun;
  sun.id = "sun";
  sun.light.kind = scene::Light::Kind::kDirectional;
  sun.light.direction = glm::normalize(glm::vec3(0.2f, -1.0f, 0.1f));
  sun.light.intensity = 2.0f;
  ASSERT_TRUE(set.add(sun));
  const RelightResult sun_added = check("directional");
  EXPECT_EQ(sun_added.counts.surfels_lit, sun_added.counts.surfels);
  // Two changes at once: a full relight.
  ASSERT_TRUE(set.modify(pointLight("a", {2, 1, 1}, 3.0f, 1.5f)));
  ASSERT_TRUE(set.modify(pointLight("c", {3, 1, 1}, 1.0f, 1.0f)));
  auto two = inc.relight(set, opt);
  ASSERT_TRUE(two);
  EXPECT_EQ(two->passes.incremental, 0);
}

// Bounces to a cap (not a converged solution to propagate a change on), so every light change
// is a full relight; emission unchanged, so what depends
// on emission alone (the emitters' sampled light at the surfels and texels) is computed once
// and reused, bit-identical to a fresh relighter's result. Intermediate bounce passes light
// the grid only when some surfel gathers from it: only the last pass's grid values are output.
TEST(RelightIncremental, EmissionOnlyWorkIsReusedWhileEmissionIsUnchanged) {
  const auto& rm = room();
  ASSERT_TRUE(rm.baked);
  Relighter r = rm.baked->relighter();
  LightSet set;
  ASSERT_TRUE(set.add(pointLight("a", {1, 1, 1}, 3.0f, 1.5f)));
  const RelightOptions opt{.max_bounces = 3, .bounce_threshold = 0.0f};
  auto first = r.relight(set, opt);
  ASSERT_TRUE(first);
  EXPECT_EQ(first->passes.surfel_emitter, 1);
  EXPECT_EQ(first->counts.surfel_emitter_reused, 0u);

  ASSERT_TRUE(set.modify(pointLight("a", {4, 1, 1}, 3.0f, 1.5f)));
  auto moved = r.relight(set, opt);
  ASSERT_TRUE(moved);
  EXPECT_EQ(moved->passes.incremental, 0);
  EXPECT_EQ(moved->passes.bounces, 3);
  EXPECT_EQ(moved->passes.surfel_emitter, 0);
  EXPECT_EQ(moved->counts.surfel_emitter_reused, 1u);
  EXPECT_EQ(moved->counts.emitter_direct_reused, 1u);
  auto fresh = rm.baked->relighter().relight(set, opt);
  ASSERT_TRUE(fresh);
  EXPECT_EQ(fresh->passes.surfel_emitter, 1);
  EXPECT_EQ(moved->lightmap_sh, fresh->lightmap_sh);
  EXPECT_EQ(moved->direct, fresh->direct);
  EXPECT_EQ(moved->grid_sh, fresh->grid_sh);

  const auto tables = r.gatherTables();
  const bool grid_gathered = std::find(tables.from_grid.begin(), tables.from_grid.end(), 1) != tables.from_grid.end();
  ASSERT_TRUE(moved->plan.grid);
  EXPECT_EQ(moved->passes.grid_lighting, grid_gathered ? 4 : 1);
  EXPECT_EQ(moved->passes.cache_lighting, 4);

  // An emission change of strength rescales the kept emitter light (no sampling);
  // invalidate(kLightState) keeps it, invalidate() does not.
  LightSet brighter = set;
  ASSERT_TRUE(brighter.setEmissive({.material = 1, .mode = EmissiveOverride::Mode::kScale, .value = glm::vec3(2.0f)}));
  auto glow = r.relight(brighter, opt);
  ASSERT_TRUE(glow);
  EXPECT_EQ(glow->passes.surfel_emitter, 0);
  EXPECT_EQ(glow->passes.emissive_direct, 0);
  EXPECT_GE(glow->counts.emitter_rescaled, 2u);
  EXPECT_NE(glow->lightmap_sh, moved->lightmap_sh);
  r.invalidate(Relighter::Forget::kLightState);
  auto kept = r.relight(brighter, opt);
  ASSERT_TRUE(kept);
  EXPECT_EQ(kept->counts.surfel_emitter_reused, 1u);
  EXPECT_EQ(kept->counts.emitter_direct_reused, 1u);
  EXPECT_EQ(kept->lightmap_sh, glow->lightmap_sh);
  r.invalidate();
  auto all = r.relight(brighter, opt);
  ASSERT_TRUE(all);
  EXPECT_EQ(all->passes.surfel_emitter, 1);
  EXPECT_EQ(all->passes.emissive_direct, 1);
  EXPECT_EQ(all->lightmap_sh, glow->lightmap_sh);
}

// Relative L1 distance of two SH arrays, and the largest difference over the largest value.
std::pair<double, double> shDistance(const std::vector<float>& a, const std::vector<float>& b) {
  double diff = 0.0, sum = 0.0, worst = 0.0, peak = 0.0;
  for (std::size_t i = 0; i < a.size() && i < b.size(); ++i) {
    diff += std::abs(double(a[i]) - b[i]), sum += std::abs(double(b[i]));
    worst = std::max(worst, std::abs(double(a[i]) - b[i])), peak = std::max(peak, std::abs(double(b[i])));
  }
  return {sum > 0.0 ? diff / sum : diff, peak > 0.0 ? worst / peak : worst};
}

// Bounces on (the defaults: to convergence): one light's change is propagated through the
// bounces on top of the last solution, and equals a full relight within the bounce
// threshold's tolerance, also after a chain of changes (nothing drifts).
TEST(RelightIncremental, WithBouncesPropagatesTheChangeAndMatchesAFullRelight) {
  const auto& rm = room();
  ASSERT_TRUE(rm.baked);
  Relighter inc = rm.baked->relighter();
  LightSet set = roomLamps();
  const RelightOptions opt;
  auto first = inc.relight(set, opt);
  ASSERT_TRUE(first);
  ASSERT_EQ(first->bounce_stop, "threshold");
  EXPECT_EQ(first->passes.incremental, 0);

  auto check = [&](const char* what) -> RelightResult {
    auto r = inc.relight(set, opt);
    EXPECT_TRUE(r);
    if (!r) return {};
    EXPECT_EQ(r->passes.incremental, 1) << what;
    EXPECT_EQ(r->bounce_stop, "threshold") << what;
    auto full = rm.baked->relighter().relight(set, opt);
    EXPECT_TRUE(full);
    if (!full) return {};
    // Both stop at the threshold short of the fixed point: measured against one converged
    // much further, the incremental answer is about as close as the full relight's.
    const RelightOptions tight{.max_bounces = 1000, .bounce_threshold = 1e-7f};
    auto ref = rm.baked->relighter().relight(set, tight);
    EXPECT_TRUE(ref);
    if (!ref) return {};
    const auto [lm_l1, lm_max] = shDistance(r->lightmap_sh, full->lightmap_sh);
    const auto [grid_l1, grid_max] = shDistance(r->grid_sh, full->grid_sh);
    const double inc_ref = shDistance(r->lightmap_sh, ref->lightmap_sh).first;
    const double full_ref = shDistance(full->lightmap_sh, ref->lightmap_sh).first;
    std::printf("%-8s rounds %d, surfels gathered %zu (full %zu); against the full relight: lightmap L1 %.2e max "
                "%.2e, grid L1 %.2e max %.2e; against the converged one: incremental %.2e, full %.2e\n",
                what, r->passes.bounces, r->counts.surfels_gathered, full->counts.surfels_gathered, lm_l1, lm_max,
                grid_l1, grid_max, inc_ref, full_ref);
    EXPECT_LT(lm_l1, 5e-3) << what;
    EXPECT_LT(lm_max, 1e-2) << what;
    EXPECT_LT(grid_l1, 5e-3) << what;
    EXPECT_LT(grid_max, 1e-2) << what;
    EXPECT_LT(inc_ref, 2.0 * full_ref + 1e-4) << what;
    EXPECT_EQ(r->direct, full->direct) << what;
    EXPECT_GT(r->passes.bounces, 0) << what;
    return std::move(r).value();
  };
  ASSERT_TRUE(set.modify(pointLight("a", {1.5f, 1, 1}, 3.0f, 1.5f)));
  const RelightResult moved = check("move");
  EXPECT_LT(moved.counts.surfels_lit, moved.counts.surfels / 2);
  // A chain of moves, an added and a removed light: each built on the last.
  for (int i = 0; i < 6; ++i) {
    ASSERT_TRUE(set.modify(pointLight("a", {1.5f + 0.3f * float(i), 1, 1}, 3.0f, 1.5f)));
    ASSERT_TRUE(inc.relight(set, opt));
  }
  ASSERT_TRUE(set.modify(pointLight("a", {3.4f, 1, 1}, 3.0f, 1.5f)));
  check("chain");
  ASSERT_TRUE(set.add(pointLight("c", {3, 1, 1.5f}, 1.0f, 1.0f)));
  check("add");
  ASSERT_TRUE(set.remove("b"));
  check("remove");
  // A solution that stopped at the cap is no base: the next change is a full relight.
  const RelightOptions capped{.max_bounces = 2, .bounce_threshold = 0.0f};
  ASSERT_TRUE(inc.relight(set, capped));
  ASSERT_TRUE(set.modify(pointLight("a", {2, 1, 1}, 3.0f, 1.5f)));
  auto after_cap = inc.relight(set, capped);
  ASSERT_TRUE(after_cap);
  EXPECT_EQ(after_cap->passes.incremental, 0);
  // Off by option.
  RelightOptions off = opt;
  off.incremental = false;
  ASSERT_TRUE(inc.relight(set, off));
  ASSERT_TRUE(set.modify(pointLight("a", {2.2f, 1, 1}, 3.0f, 1.5f)));
  auto full_again = inc.relight(set, off);
  ASSERT_TRUE(full_again);
  EXPECT_EQ(full_again->passes.incremental, 0);
}

// Surfels of a probe-lit block gather their bounce light from the grid: the propagation
// follows a change through the grid caches to them as well. (In a room this small each round
// relights every cache; the sparse rounds are measured on zdm2 by relight_bench.)
TEST(RelightIncremental, WithBouncesReachesSurfelsThatGatherFromTheGrid) {
  scene::Scene s;
  const int m = addMaterial(s, glm::vec3(0.6f, 0.5f, 0.4f));
  addBox(s, {0, 0, 0}, {8, 2, 2}, /*inward=*/true, m);
  const std::size_t first_block_mesh = s.meshes.size();
  addBox(s, {1.6f, 0.0f, 0.6f}, {2.4f, 0.8f, 1.4f}, /*inward=*/false, m);
  for (std::size_t i = first_block_mesh; i < s.meshes.size(); ++i) s.meshes[i].probe_lit = true;
  auto o = smallOptions();
  o.surfels = 8192;  // fine enough that a short-range light's change stays local
  o.lightmap_resolution = 64;
  o.grid = precompute::GridMode::kOn;
  o.grid_resolution = 6;
  auto baked = Baked::make(std::move(s), o);
  ASSERT_TRUE(baked);
  Relighter inc = baked->relighter();
  const auto tables = inc.gatherTables();
  const auto from_grid = std::count(tables.from_grid.begin(), tables.from_grid.end(), 1);
  ASSERT_GT(from_grid, 0) << "the block's surfels gather from the grid";
  LightSet set;
  ASSERT_TRUE(set.add(pointLight("a", {2, 1.2f, 0.3f}, 3.0f, 1.0f)));
  ASSERT_TRUE(set.add(pointLight("b", {6, 1.5f, 1}, 40.0f)));
  const RelightOptions opt;
  auto first = inc.relight(set, opt);
  ASSERT_TRUE(first);
  ASSERT_EQ(first->bounce_stop, "threshold");
  ASSERT_TRUE(set.modify(pointLight("a", {2, 1.2f, 1.7f}, 3.0f, 1.0f)));
  auto moved = inc.relight(set, opt);
  ASSERT_TRUE(moved);
  EXPECT_EQ(moved->passes.incremental, 1);
  auto full = baked->relighter().relight(set, opt);
  ASSERT_TRUE(full);
  const auto [lm_l1, lm_max] = shDistance(moved->lightmap_sh, full->lightmap_sh);
  const auto [grid_l1, grid_max] = shDistance(moved->grid_sh, full->grid_sh);
  double block_diff = 0.0, block_sum = 0.0;  // radiosity of the surfels that gather from the grid
  for (std::size_t k = 0; k < tables.from_grid.size(); ++k)
    if (tables.from_grid[k]) {
      const glm::vec3 d = glm::abs(moved->surfel_radiosity[k] - full->surfel_radiosity[k]);
      block_diff += d.x + d.y + d.z;
      const glm::vec3 b = glm::abs(full->surfel_radiosity[k]);
      block_sum += b.x + b.y + b.z;
    }
  std::printf("%td surfels gather from the grid; %zu gathers in %d rounds of %zu surfels; lightmap L1 %.2e, grid L1 "
              "%.2e, their radiosity L1 %.2e\n",
              from_grid, moved->counts.surfels_gathered, moved->passes.bounces, moved->counts.surfels, lm_l1, grid_l1,
              block_diff / block_sum);
  EXPECT_LT(lm_l1, 5e-3);
  EXPECT_LT(grid_l1, 5e-3);
  EXPECT_LT(grid_max, 2e-2);
  ASSERT_GT(block_sum, 0.0);
  EXPECT_LT(block_diff / block_sum, 5e-3);
}

TEST(RelightIncremental, UnchangedLightSetReEmitsTheKeptResult) {
  const auto& rm = room();
  ASSERT_TRUE(rm.baked);
  Relighter r = rm.baked->relighter();
  LightSet set;
  ASSERT_TRUE(set.add(pointLight("a", {1, 1, 1}, 3.0f, 1.5f)));
  const RelightOptions opt;  // bounces on, emitter in the room: the expensive case
  auto first = r.relight(set, opt);
  ASSERT_TRUE(first);
  ASSERT_GT(first->passes.bounces, 0);
  EXPECT_EQ(first->passes.unchanged, 0);
  // The same values written again (a new version, as a daemon update would make).
  ASSERT_TRUE(set.modify(pointLight("a", {1, 1, 1}, 3.0f, 1.5f)));
  auto again = r.relight(set, opt);
  ASSERT_TRUE(again);
  EXPECT_EQ(again->passes.unchanged, 1);
  EXPECT_EQ(again->passes.bounces, 0);
  EXPECT_EQ(again->passes.surfel_direct + again->passes.pulls + again->passes.cache_lighting, 0);
  EXPECT_EQ(again->version, set.version());
  EXPECT_GT(again->version, first->version);
  EXPECT_EQ(again->bounce_stop, first->bounce_stop);
  EXPECT_EQ(again->bounce_log.size(), first->bounce_log.size());
  EXPECT_EQ(again->lightmap_sh, first->lightmap_sh);
  EXPECT_EQ(again->direct, first->direct);
  EXPECT_EQ(again->grid_sh, first->grid_sh);
  EXPECT_EQ(again->texel_valid, first->texel_valid);
  // A different option is a change: computed again, and equal to a fresh relighter's result.
  RelightOptions fewer = opt;
  fewer.max_bounces = 1;
  auto changed = r.relight(set, fewer);
  ASSERT_TRUE(changed);
  EXPECT_EQ(changed->passes.unchanged, 0);
  Relighter fresh = rm.baked->relighter();
  auto full = fresh.relight(set, fewer);
  ASSERT_TRUE(full);
  expectSame(*changed, *full, "after unchanged");
}

// ---- kernels, determinism --------------------------------------------------------------------

TEST(RelightKernels, CapBandFactorsMatchProjectRuntimeLink) {
  for (float w : {0.0f, 0.01f, 0.3f, 1.0f, 2.0f, 3.5f, 4.0f}) {
    const glm::vec3 d = glm::normalize(glm::vec3(0.3f, -0.5f, 0.8f));
    float ref[16], y[16], k[4];
    links::projectRuntimeLink(d, w, 4, ref);
    capBandFactors(w, k);
    sh::evalBasis(4, d, y);
    for (int i = 0; i < 16; ++i) EXPECT_NEAR(k[sh::bandOf(i)] * y[i], ref[i], 2e-5f) << "omega/pi " << w << " i " << i;
  }
}

TEST(RelightKernels, SimdMatchesScalarForBothLinkForms) {
  if (!Relighter::simdAvailable()) GTEST_SKIP() << "no AVX2 + F16C on this CPU";
  const auto& rm = room();
  ASSERT_TRUE(rm.baked);
  LightSet set;
  ASSERT_TRUE(set.add(pointLight("a", {1, 1, 1}, 3.0f)));
  Sky sky;
  sky.radiance = glm::vec3(0.1f);
  ASSERT_TRUE(set.setSky(sky));
  for (LinkForm form : {LinkForm::kProjected, LinkForm::kRuntime})
    for (int bands : {1, 2, 3, 4}) {
      if (form == LinkForm::kProjected && bands > rm.baked->p.options.bands) continue;
      Relighter a = rm.baked->relighter(), b = rm.baked->relighter();
      auto simd = a.relight(set, {.link_form = form, .bands = bands, .max_bounces = 1, .kernel = Kernel::kAuto});
      auto scalar = b.relight(set, {.link_form = form, .bands = bands, .max_bounces = 1, .kernel = Kernel::kScalar});
      ASSERT_TRUE(simd && scalar);
      EXPECT_EQ(simd->kernel, "avx2");
      EXPECT_EQ(scalar->kernel, "scalar");
      float max_l00 = 0.0f;
      for (std::size_t t = 0; t < scalar->lightmap_sh.size(); ++t) max_l00 = std::max(max_l00, std::abs(scalar->lightmap_sh[t]));
      ASSERT_GT(max_l00, 0.0f);
      for (std::size_t i = 0; i < simd->lightmap_sh.size(); ++i)
        ASSERT_NEAR(simd->lightmap_sh[i], scalar->lightmap_sh[i], 2e-5f * max_l00)
            << "form " << int(form) << " bands " << bands << " index " << i;
      for (std::size_t i = 0; i < simd->grid_sh.size(); ++i)
        ASSERT_NEAR(simd->grid_sh[i], scalar->grid_sh[i], 2e-5f * max_l00);
    }
}

TEST(RelightKernels, RuntimeFormAgreesWithProjectedForm) {
  const auto& f = furnace();
  ASSERT_TRUE(f.baked);
  Relighter r = f.baked->relighter();
  // One bounce, so the (reflected-only) lightmap SH has a value.
  auto a = r.relight(LightSet{}, {.link_form = LinkForm::kProjected, .max_bounces = 1});
  auto b = r.relight(LightSet{}, {.link_form = LinkForm::kRuntime, .max_bounces = 1});
  ASSERT_TRUE(a && b);
  // Near-uniform radiosity: both forms integrate the same visible solid angle, so L00 agrees.
  const int nc = a->coeffCount();
  for (std::size_t t = 0; t < a->texel_valid.size(); ++t)
    if (a->texel_valid[t]) {
      ASSERT_GT(a->lightmap_sh[t * 3 * nc], 0.0f);
      EXPECT_NEAR(a->lightmap_sh[t * 3 * nc], b->lightmap_sh[t * 3 * nc], 0.01f * a->lightmap_sh[t * 3 * nc]);
    }
}

TEST(RelightDeterminism, OneAndTwoThreadsAreBitIdentical) {
  const auto& rm = room();
  ASSERT_TRUE(rm.baked);
  LightSet set;
  ASSERT_TRUE(set.add(pointLight("a", {1, 1, 1}, 3.0f)));
  auto run = [&](int threads) {
    tbb::global_control limit(tbb::global_control::max_allowed_parallelism, threads);
    Relighter r = rm.baked->relighter();
    auto res = r.relight(set, {.max_bounces = 3});
    EXPECT_TRUE(res);
    return std::move(res).value();
  };
  const RelightResult one = run(1), two = run(2);
  ASSERT_EQ(one.lightmap_sh.size(), two.lightmap_sh.size());
  EXPECT_EQ(0, std::memcmp(one.lightmap_sh.data(), two.lightmap_sh.data(), one.lightmap_sh.size() * sizeof(float)));
  EXPECT_EQ(0, std::memcmp(one.grid_sh.data(), two.grid_sh.data(), one.grid_sh.size() * sizeof(float)));
  ASSERT_EQ(one.bounce_log.size(), two.bounce_log.size());
  for (std::size_t k = 0; k < one.bounce_log.size(); ++k) EXPECT_EQ(one.bounce_log[k].added_flux, two.bounce_log[k].added_flux);
}

TEST(RelightDeterminism, IncrementalWithBouncesIsBitIdenticalForAnyThreadCount) {
  const auto& rm = room();
  ASSERT_TRUE(rm.baked);
  auto run = [&](int threads) {
    tbb::global_control limit(tbb::global_control::max_allowed_parallelism, threads);
    Relighter r = rm.baked->relighter();
    LightSet set;
    EXPECT_TRUE(set.add(pointLight("a", {1, 1, 1}, 3.0f, 2.0f)));
    EXPECT_TRUE(r.relight(set));
    EXPECT_TRUE(set.modify(pointLight("a", {1.6f, 1, 1.2f}, 3.0f, 2.0f)));
    auto res = r.relight(set);
    EXPECT_TRUE(res);
    EXPECT_EQ(res->passes.incremental, 1);
    return std::move(res).value();
  };
  const RelightResult one = run(1), two = run(2);
  ASSERT_EQ(one.lightmap_sh.size(), two.lightmap_sh.size());
  EXPECT_EQ(0, std::memcmp(one.lightmap_sh.data(), two.lightmap_sh.data(), one.lightmap_sh.size() * sizeof(float)));
  EXPECT_EQ(0, std::memcmp(one.grid_sh.data(), two.grid_sh.data(), one.grid_sh.size() * sizeof(float)));
  EXPECT_EQ(one.surfel_radiosity, two.surfel_radiosity);
  EXPECT_EQ(one.counts.surfels_gathered, two.counts.surfels_gathered);
  ASSERT_EQ(one.bounce_log.size(), two.bounce_log.size());
  for (std::size_t k = 0; k < one.bounce_log.size(); ++k) EXPECT_EQ(one.bounce_log[k].added_flux, two.bounce_log[k].added_flux);
}

// The pull's areas: a surfel no cache sees adds no area to its nodes; with every surfel seen
// (or no flags at all) they are the tree's own areas, bit for bit.
TEST(RelightPull, UnseenSurfelsAddNoAreaToTheirNodes) {
  const auto& rm = room();
  ASSERT_TRUE(rm.baked);
  precompute::Precomputation p = rm.baked->p;
  const auto& t = p.tree;
  for (const bool flags : {true, false}) {
    p.surfel_seen.assign(flags ? p.surfels.size() : 0, 1);
    auto all = pullAreas(p);
    ASSERT_TRUE(all) << all.status().toString();
    EXPECT_EQ(all->unseen, 0u);
    EXPECT_EQ(all->surfel, p.surfels.area);
    for (std::size_t n = 0; n < t.nodeCount(); ++n)
      ASSERT_EQ(all->inv_node[n], t.area[n] > 0.0f ? 1.0f / t.area[n] : 0.0f) << "node " << n;
  }
  // Hide the left half of the root's surfels.
  p.surfel_seen.assign(p.surfels.size(), 1);
  const std::uint32_t split = t.end[std::size_t(t.left[0])];
  for (std::uint32_t s = 0; s < split; ++s) p.surfel_seen[s] = 0;
  auto half = pullAreas(p);
  ASSERT_TRUE(half);
  EXPECT_EQ(half->unseen, split);
  EXPECT_EQ(half->inv_node[std::size_t(t.left[0])], 0.0f);
  EXPECT_EQ(half->inv_node[std::size_t(t.right[0])], 1.0f / t.area[std::size_t(t.right[0])]);
  EXPECT_NEAR(1.0f / half->inv_node[0], t.area[std::size_t(t.right[0])], 1e-6f * t.area[0]);
  p.surfel_seen.pop_back();
  EXPECT_FALSE(pullAreas(p));
}

// A link carries the radiosity of what some cache sees of its node: surfels behind the
// scenes, however bright, do not brighten the caches that link their node.
TEST(RelightPull, HiddenSurfelsDoNotBrightenTheCaches) {
  const auto& rm = room();
  ASSERT_TRUE(rm.baked);
  LightSet set;
  ASSERT_TRUE(set.add(pointLight("a", {1, 1, 1}, 3.0f)));
  auto relightWith = [&](const precompute::Precomputation& p) {
    auto r = Relighter::create(rm.baked->scene, *rm.baked->accel, p);
    EXPECT_TRUE(r) << r.status().toString();
    auto res = r->relight(set, {.max_bounces = 0});
    EXPECT_TRUE(res) << res.status().toString();
    return std::move(res).value();
  };
  const RelightResult base = relightWith(rm.baked->p);
  // Every surfel of the room is seen: the flags change nothing.
  ASSERT_EQ(std::count(rm.baked->p.surfel_seen.begin(), rm.baked->p.surfel_seen.end(), 1),
            static_cast<std::ptrdiff_t>(rm.baked->p.surfels.size()));
  precompute::Precomputation no_flags = rm.baked->p;
  no_flags.surfel_seen.clear();
  expectSame(relightWith(no_flags), base, "no flags");
  // Mark the ceiling right above the light unseen: the brightest surfels of the room, so
  // every cache that linked a node holding them gets less light, none gets more.
  precompute::Precomputation hidden = rm.baked->p;
  std::size_t marked = 0;
  for (std::size_t s = 0; s < hidden.surfels.size(); ++s)
    if (glm::length(hidden.surfels.position[s] - glm::vec3(1, 2, 1)) < 0.6f) hidden.surfel_seen[s] = 0, ++marked;
  ASSERT_GT(marked, 0u);
  const RelightResult dim = relightWith(hidden);
  const int bands = base.bands, nc = bands * bands;
  std::size_t darker = 0, brighter = 0;
  for (std::size_t texel = 0; texel * 3 * nc < base.lightmap_sh.size(); ++texel) {
    const float a = base.lightmap_sh[texel * 3 * nc], b = dim.lightmap_sh[texel * 3 * nc];  // R, band 0
    darker += b < a * (1.0f - 1e-4f) ? 1 : 0;
    brighter += b > a * (1.0f + 1e-4f) + 1e-9f ? 1 : 0;
  }
  EXPECT_GT(darker, 0u);
  EXPECT_EQ(brighter, 0u);
}

TEST(RelightInto, ReusedResultHoldsNoStaleValues) {
  const auto& rm = room();
  ASSERT_TRUE(rm.baked);
  Relighter r = rm.baked->relighter();
  LightSet set;
  ASSERT_TRUE(set.add(pointLight("a", {1, 1, 1}, 3.0f)));
  RelightResult reused;
  ASSERT_TRUE(r.relightInto(set, {.max_bounces = 2}, reused));
  EXPECT_EQ(reused.bounce_log.size(), 2u);
  const float* before = reused.lightmap_sh.data();
  // Lamp off, light removed: only the emissive ceiling lamp remains.
  LightSet dark;
  ASSERT_TRUE(dark.setEmissive({.material = 1, .mode = EmissiveOverride::Mode::kScale, .value = glm::vec3(0.0f)}));
  ASSERT_TRUE(r.relightInto(dark, {.max_bounces = 0}, reused));
  EXPECT_EQ(reused.lightmap_sh.data(), before) << "the buffer should be reused";
  EXPECT_TRUE(reused.bounce_log.empty());
  EXPECT_EQ(reused.passes.surfel_direct, 0);
  for (float v : reused.lightmap_sh) ASSERT_EQ(v, 0.0f);
  for (const auto& d : reused.direct) ASSERT_EQ(d, glm::vec3(0.0f));
  EXPECT_EQ(reused.version, dark.version());
}

TEST(RelightArtifact, RelightFromAMappedArtifactEqualsInMemory) {
  const auto& rm = room();
  ASSERT_TRUE(rm.baked);
  lightlink::testing::TempDir dir;
  const std::string path = (dir / "room.llk").string();
  ASSERT_TRUE(precompute::save(rm.baked->p, path, 42));
  auto loaded = precompute::open(path);
  ASSERT_TRUE(loaded) << loaded.status().toString();
  EXPECT_TRUE(loaded->p.lightmap_links.node.empty());  // links stay in the mapping
  auto mapped = Relighter::create(rm.baked->scene, *rm.baked->accel, loaded->p, loaded->lightmap_links,
                                  loaded->grid_links);
  ASSERT_TRUE(mapped) << mapped.status().toString();
  Relighter memory = rm.baked->relighter();
  LightSet set;
  ASSERT_TRUE(set.add(pointLight("a", {1, 1, 1}, 3.0f)));
  for (LinkForm form : {LinkForm::kProjected, LinkForm::kRuntime}) {
    auto a = mapped->relight(set, {.link_form = form, .max_bounces = 2});
    auto b = memory.relight(set, {.link_form = form, .max_bounces = 2});
    ASSERT_TRUE(a && b);
    EXPECT_EQ(a->lightmap_sh, b->lightmap_sh);
    EXPECT_EQ(a->grid_sh, b->grid_sh);
  }
}

TEST(RelightOptionsCheck, RejectsBadOptions) {
  const auto& rm = room();
  ASSERT_TRUE(rm.baked);
  Relighter r = rm.baked->relighter();
  EXPECT_FALSE(r.relight(LightSet{}, {.bands = 5}));
  EXPECT_FALSE(r.relight(LightSet{}, {.link_form = LinkForm::kProjected, .bands = 4}));
  EXPECT_FALSE(r.relight(LightSet{}, {.bounce_threshold = std::nanf("")}));
  LightSet set;
  ASSERT_TRUE(set.setEmissive({.material = 99, .mode = EmissiveOverride::Mode::kScale, .value = glm::vec3(2.0f)}));
  auto bad = r.relight(set, {});
  ASSERT_FALSE(bad);
  EXPECT_NE(bad.status().message().find("emissive[0].material"), std::string::npos) << bad.status().message();
}

TEST(RelightEmissive, OverrideScalesTheLampsDirectAndIndirectLight) {
  const auto& rm = room();
  ASSERT_TRUE(rm.baked);
  Relighter r = rm.baked->relighter();
  // One bounce: the lamp's direct light is sampled into `direct`, its reflection is in the SH.
  auto base = r.relight(LightSet{}, {.max_bounces = 1});
  LightSet set;
  ASSERT_TRUE(set.setEmissive({.material = 1, .mode = EmissiveOverride::Mode::kScale, .value = glm::vec3(3.0f)}));
  auto scaled = r.relight(set, {.max_bounces = 1});
  ASSERT_TRUE(base && scaled);
  EXPECT_TRUE(base->plan.emissive);
  EXPECT_EQ(base->passes.emissive_direct, 1);
  double a = 0, b = 0;
  for (std::size_t i = 0; i < base->lightmap_sh.size(); ++i) a += base->lightmap_sh[i], b += scaled->lightmap_sh[i];
  EXPECT_GT(a, 0.0);
  EXPECT_NEAR(b / a, 3.0, 1e-3);
  double da = 0, db = 0;
  for (std::size_t t = 0; t < base->direct.size(); ++t) da += base->direct[t].x, db += scaled->direct[t].x;
  EXPECT_GT(da, 0.0);
  EXPECT_NEAR(db / da, 3.0, 1e-3);
  LightSet off;
  ASSERT_TRUE(off.setEmissive({.material = 1, .mode = EmissiveOverride::Mode::kRadiance, .value = glm::vec3(0.0f)}));
  auto dark = r.relight(off, {});
  ASSERT_TRUE(dark);
  EXPECT_FALSE(dark->plan.emissive);
  EXPECT_EQ(dark->passes.emission, 0);
}

}  // namespace
}  // namespace lightlink::relight
