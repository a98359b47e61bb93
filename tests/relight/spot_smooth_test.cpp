// A narrow spot light that lights a few surfels (seed 000 Fig. 7b, issue 46 deliverable 5):
// the floor texels that see the lit patch get its light through a few link rays each, so
// neighbouring texels (different rays, different cuts) jump by the rays' noise. The test
// measures the jump between adjacent floor texels as the change of their ratio to a reference
// (the lit wall patch integrated over by quadrature: smooth), and holds RelightOptions::
// smooth_indirect to removing most of it without moving the mean.
#include <algorithm>
#include <cmath>
#include <numbers>

#include <gtest/gtest.h>

#include "core/scene/light_eval.h"
#include "core/sh/sh.h"
#include "tests/relight/relight_fixture.h"

namespace lightlink::relight {
namespace {

using namespace lightlink::relight::testing;
constexpr double kPi = std::numbers::pi;

struct Jumps {
  double mean_ratio = 0.0;     // baked / reference over the floor texels the patch lights
  double adjacent = 0.0;       // mean |ratio(t) - ratio(t')| over adjacent such texels
  int texels = 0, pairs = 0;
};

TEST(SpotSmooth, NeighbouringTexelsDoNotJumpUnderASmallLitPatch) {
  constexpr float kRho = 0.8f;
  scene::Scene s;
  const int black = addMaterial(s, glm::vec3(0.0f));
  const int wall = addMaterial(s, glm::vec3(kRho));
  addQuad(s, {0, 0, 0}, {0, 0, 4}, {4, 0, 4}, {4, 0, 0}, black);        // floor, +y: reflects nothing
  addQuad(s, {0, 0, 0}, {0, 2.5f, 0}, {0, 2.5f, 4}, {0, 0, 4}, wall);   // wall x = 0, +x
  auto o = smallOptions();
  o.links = 128;  // the medium preset's links and rays
  o.rays = 1024;
  auto baked = Baked::make(std::move(s), o);
  ASSERT_TRUE(baked);
  LightSet set;
  LightEntry spot;  // a 10-degree cone onto the wall: ~0.2 m^2, about 15 surfels
  spot.id = "spot";
  spot.light.kind = scene::Light::Kind::kSpot;
  spot.light.position = {1.5f, 1.5f, 2.0f};
  spot.light.direction = glm::normalize(glm::vec3(-1.0f, -0.2f, 0.0f));
  spot.light.intensity = 50.0f;
  spot.light.outer_cone_angle = 0.17f;
  spot.light.inner_cone_angle = 0.136f;
  ASSERT_TRUE(set.add(spot));

  // Reference floor irradiance: the wall's reflected spot light, a 1 cm quadrature.
  std::vector<glm::vec3> wp;
  std::vector<double> wb;  // rho E dA
  constexpr int kNy = 250, kNz = 400;
  for (int i = 0; i < kNy; ++i)
    for (int j = 0; j < kNz; ++j) {
      const glm::vec3 x(0.0f, (i + 0.5f) * 2.5f / kNy, (j + 0.5f) * 4.0f / kNz);
      const double e = scene::irradianceFrom(spot.light, x, {1, 0, 0}).x;
      if (e > 0.0) wp.push_back(x), wb.push_back(kRho * e * (2.5 / kNy) * (4.0 / kNz));
    }
  const auto& lm = baked->p.lightmap;
  std::vector<double> eref(lm.size(), 0.0);
  double emax = 0.0;
  for (std::size_t c = 0; c < lm.size(); ++c) {
    if (!lm.valid[c] || lm.normal[c].y < 0.5f || lm.pushed[c]) continue;
    for (std::size_t k = 0; k < wp.size(); ++k) {
      const glm::vec3 d = wp[k] - lm.position[c];
      const double d2 = glm::dot(d, d), inv = 1.0 / std::sqrt(d2);
      if (d.y > 0.0f && d.x < 0.0f) eref[c] += wb[k] * (d.y * inv) * (-d.x * inv) / (kPi * d2);
    }
    emax = std::max(emax, eref[c]);
  }
  auto measure = [&](bool smooth) {
    Relighter r = baked->relighter();
    auto res = r.relight(set, {.max_bounces = 1, .bounce_threshold = 0.0f, .smooth_indirect = smooth});
    EXPECT_TRUE(res) << res.status().toString();
    Jumps j;
    if (!res) return j;
    const int nc = res->coeffCount();
    std::vector<double> ratio(lm.size(), 0.0);
    std::vector<int> cache_of(std::size_t(res->width) * res->height, -1);
    for (std::size_t c = 0; c < lm.size(); ++c) {
      if (eref[c] < 0.1 * emax) continue;  // where the patch's light is the floor's light
      const float e = sh::irradiance(res->bands, res->lightmap_sh.data() + std::size_t(lm.texel[c]) * 3 * nc, {0, 1, 0});
      ratio[c] = e / eref[c];
      cache_of[lm.texel[c]] = int(c);
      j.mean_ratio += ratio[c], ++j.texels;
    }
    for (std::size_t c = 0; c < lm.size(); ++c) {
      if (cache_of[lm.texel[c]] != int(c)) continue;
      for (const std::size_t nb : {std::size_t(lm.texel[c]) + 1, std::size_t(lm.texel[c]) + res->width}) {
        if (nb >= cache_of.size() || cache_of[nb] < 0) continue;
        j.adjacent += std::abs(ratio[c] - ratio[std::size_t(cache_of[nb])]), ++j.pairs;
      }
    }
    j.mean_ratio /= std::max(j.texels, 1);
    j.adjacent /= std::max(j.pairs, 1);
    return j;
  };
  const Jumps raw = measure(false), smooth = measure(true);
  ASSERT_GT(raw.texels, 100);
  ASSERT_GT(raw.pairs, 200);
  // Measured: adjacent jump 0.40 without the filter (the reference's own change between
  // neighbours is ~0.18 of their value, its ratio's 0), 0.076 with it; mean 0.977 -> 0.982.
  EXPECT_GT(raw.adjacent, 0.25) << "the jump this test is about is gone: revisit it";
  EXPECT_LT(smooth.adjacent, 0.12);
  EXPECT_NEAR(smooth.mean_ratio, 1.0, 0.05);
  EXPECT_NEAR(smooth.mean_ratio, raw.mean_ratio, 0.02);
}

}  // namespace
}  // namespace lightlink::relight
