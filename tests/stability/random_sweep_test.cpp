// Property sweep: random scenes from a seeded generator (random_scene.h: a room with boxes,
// 1-5 mm slabs, double-sided thin walls, emitters, point and spot lights, some inside
// geometry), each baked and relit with bounces. For every scene:
//   - no NaN/Inf anywhere; radiosity, direct and SH means (L00) never negative;
//   - direct irradiance per texel <= the sum over baked lights of the *unoccluded*
//     irradiance there (+1e-4 rel.), plus 2 pi L_max for baked emitters (pi L_max is the
//     most a surface can get from emitters of radiance <= L_max; x2 headroom for the
//     sampling noise of the emitter estimator);
//   - indirect irradiance per lightmap texel <= 1.04 x the largest surfel radiosity (a
//     cache sees at most radiance B_max / pi from every direction; the 3-band clamped-cosine
//     kernel overshoots by at most 3.1 %, computed in docs/stability.md);
//   - grid caches: pi x mean radiance <= 1.04 B_max;
//   - surfel radiosity B_s <= pi L_e + rho_s (E_unoccluded(s) + 1.04 B_max): no surfel gets
//     more than its lights and the brightest surface could give it;
//   - energy: total flux after all bounces <= 1.1 x Phi_0 / (1 - rho_max), the geometric
//     series of the direct (+ emitted) flux Phi_0 (bounded: rho_max < 0.9).
#include <algorithm>
#include <cmath>
#include <numbers>

#include <gtest/gtest.h>

#include "tests/stability/random_scene.h"

namespace lightlink::stability {
namespace {

constexpr float kPi = std::numbers::pi_v<float>;
constexpr int kScenes = 8;

glm::vec3 unoccluded(const LightSet& set, glm::vec3 p, glm::vec3 n, bool baked_only) {
  glm::vec3 e(0.0f);
  for (const auto& l : set.lights())
    if (!baked_only || l.baked) e += scene::irradianceFrom(l.light, p, n);
  return e;
}

float maxComponent(glm::vec3 v) { return std::max({v.x, v.y, v.z}); }

TEST(StabilityProperty, RandomScenesStayFiniteNonNegativeAndEnergyBounded) {
  // Tightest value / bound seen over all scenes, per bound (printed: how close each comes).
  double t_direct = 0, t_indirect = 0, t_grid = 0, t_surfel = 0, t_flux = 0, t_ratio = 0;
  auto tight = [](double& t, double value, double bound) {
    if (bound > 0) t = std::max(t, value / bound);
  };
  for (int i = 0; i < kScenes; ++i) {
    const std::uint64_t seed = 1000 + std::uint64_t(i);
    SCOPED_TRACE("random scene seed " + std::to_string(seed));
    RandomScene rs = makeRandomScene(seed);
    auto o = tinyOptions();
    o.surfels = 768;
    o.rays = 100;
    o.links = 24;
    o.lightmap_resolution = 32;
    o.grid = precompute::GridMode::kOn;
    o.grid_resolution = 4;
    o.seed = seed;
    auto baked = Baked::make(rs.scene, o);
    ASSERT_TRUE(baked);
    const auto& p = baked->p;
    relight::Relighter r = baked->relighter();
    auto direct_only = r.relight(rs.lights, {.max_bounces = 0, .emitter_samples = 8});
    ASSERT_TRUE(direct_only) << direct_only.status().toString();
    auto res = r.relight(rs.lights, {.max_bounces = 6, .bounce_threshold = 1e-3f, .emitter_samples = 8});
    ASSERT_TRUE(res) << res.status().toString();
    ASSERT_EQ(countBadValues(*res, "seed " + std::to_string(seed)), 0u);

    float le_max = 0.0f;
    for (const auto& m : baked->scene.materials) le_max = std::max(le_max, maxComponent(m.emissive_factor) * m.emissive_strength);
    float b_max = 0.0f;
    for (const auto& b : res->surfel_radiosity) b_max = std::max(b_max, maxComponent(b));

    // Direct per texel.
    const auto& lm = p.lightmap;
    std::size_t direct_checked = 0;
    for (std::size_t c = 0; c < lm.size(); ++c) {
      if (!lm.valid[c]) continue;
      const glm::vec3 bound = unoccluded(rs.lights, lm.position[c], lm.normal[c], true) * 1.0001f + 2.0f * kPi * le_max + 1e-6f;
      const glm::vec3 d = res->direct[lm.texel[c]];
      for (int ch = 0; ch < 3; ++ch) {
        ASSERT_LE(d[ch], bound[ch]) << "cache " << c << " channel " << ch << ": direct above the unoccluded lights";
        tight(t_direct, d[ch], bound[ch]);
      }
      ++direct_checked;
    }
    EXPECT_GT(direct_checked, 50u);
    // Indirect per texel, grid caches.
    const int nc = res->coeffCount();
    for (std::size_t c = 0; c < lm.size(); ++c) {
      if (!lm.valid[c]) continue;
      const glm::vec3 e = shIrradiance(res->lightmap_sh.data() + std::size_t(lm.texel[c]) * 3 * nc, res->bands, lm.normal[c]);
      ASSERT_LE(maxComponent(e), 1.04f * b_max + 1e-6f) << "cache " << c << ": indirect above the brightest surface";
      tight(t_indirect, maxComponent(e), 1.04 * b_max);
    }
    for (std::size_t g = 0; g < p.grid.size(); ++g)
      for (int ch = 0; ch < 3; ++ch) {
        const float mean_e = res->grid_sh[g * 3 * nc + std::size_t(ch) * nc] * std::sqrt(kPi) / 2.0f;
        ASSERT_LE(mean_e, 1.04f * b_max + 1e-6f) << "grid cache " << g;
        tight(t_grid, mean_e, 1.04 * b_max);
      }
    // Surfels.
    for (std::size_t s = 0; s < p.surfels.size(); ++s) {
      const glm::vec3 e = unoccluded(rs.lights, p.surfels.position[s], p.surfels.normal[s], false);
      const glm::vec3 bound = kPi * p.surfels.emission[s] + p.surfels.albedo[s] * (e * 1.0001f + 1.04f * b_max) + 1e-6f;
      for (int ch = 0; ch < 3; ++ch) {
        ASSERT_LE(res->surfel_radiosity[s][ch], bound[ch]) << "surfel " << s << " channel " << ch;
        tight(t_surfel, res->surfel_radiosity[s][ch], bound[ch]);
      }
    }
    // Energy.
    double phi0 = 0.0;
    for (std::size_t s = 0; s < p.surfels.size(); ++s)
      for (int ch = 0; ch < 3; ++ch) phi0 += double(direct_only->surfel_radiosity[s][ch]) * p.surfels.area[s];
    if (!res->bounce_log.empty()) {
      EXPECT_LE(res->bounce_log.back().total_flux, 1.1 * phi0 / (1.0 - rs.max_albedo)) << "flux diverges";
      tight(t_flux, res->bounce_log.back().total_flux, 1.1 * phi0 / (1.0 - rs.max_albedo));
      for (std::size_t k = 1; k < res->bounce_log.size(); ++k) {
        EXPECT_LE(res->bounce_log[k].added_flux, 1.03 * rs.max_albedo * res->bounce_log[k - 1].added_flux + 1e-9)
            << "bounce " << k + 1 << " added more than rho_max times the previous bounce";
        tight(t_ratio, res->bounce_log[k].added_flux, 1.03 * rs.max_albedo * res->bounce_log[k - 1].added_flux);
      }
    }
    std::printf("seed %llu: %zu surfels, %zu caches (%zu valid), %zu grid, %zu bounces (%s), B_max %.3g\n",
                static_cast<unsigned long long>(seed), p.surfels.size(), lm.size(), lm.validCount(), p.grid.size(),
                res->bounce_log.size(), res->bounce_stop.c_str(), b_max);
  }
  std::printf("tightest value/bound over %d scenes: direct %.3f, indirect %.3f, grid %.3f, surfel %.3f, flux %.3f, "
              "bounce ratio %.3f\n",
              kScenes, t_direct, t_indirect, t_grid, t_surfel, t_flux, t_ratio);
}

}  // namespace
}  // namespace lightlink::stability
