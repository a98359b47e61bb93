// mm- and km-scale scenes (DESIGN.md sec 6): the Cornell box scaled by s = 1e-3 and 1e3 must
// give the irradiance of the 1 m box up to the scale law, i.e. every epsilon and ray offset
// must follow the scene size.
//
// Scale law. Scaling every length by s with point intensities in candela fixed, a point
// light's irradiance I cos / d^2 scales as 1/s^2; radiosity B = rho E follows, and the
// radiance B / pi a cache receives from a surface is independent of distance, so indirect
// light scales as 1/s^2 too. Emitters are specified by radiance, which has no length in it:
// their light would not scale. So the test also scales the emitters' radiance by 1/s^2
// (an emissive override), and then every output obeys E_s = E_1 / s^2.
#include <algorithm>
#include <cmath>
#include <vector>

#include <gtest/gtest.h>

#include "core/scene/load.h"
#include "tests/common/testing.h"
#include "tests/stability/stability_fixture.h"

namespace lightlink::stability {
namespace {

const std::string kDemo = (testing::sourceDir() / "clients/demo/cornell_box.gltf").string();

struct ScaledBake {
  double s = 1.0;
  std::unique_ptr<Baked> baked;
  RelightResult result;
};

ScaledBake bakeAtScale(double s) {
  ScaledBake out;
  out.s = s;
  auto loaded = scene::loadGltf(kDemo);
  EXPECT_TRUE(loaded) << loaded.status().toString();
  if (!loaded) return out;
  scene::Scene scene = std::move(loaded).value();
  // Positions are already in world space; bounds and scale are recomputed by Baked::make.
  for (auto& m : scene.meshes)
    for (auto& p : m.positions) p = glm::vec3(glm::dvec3(p) * s);
  for (auto& l : scene.lights) l.position = glm::vec3(glm::dvec3(l.position) * s), l.range *= float(s);
  LightSet set = LightSet::fromSceneLights(scene.lights);
  // Emitters: radiance scaled by 1/s^2 (see the scale law above).
  for (std::size_t m = 0; m < scene.materials.size(); ++m) {
    if (!scene.materials[m].isEmissive()) continue;
    EXPECT_TRUE(set.setEmissive({.material = int(m),
                                 .mode = relight::EmissiveOverride::Mode::kScale,
                                 .value = glm::vec3(float(1.0 / (s * s)))}));
  }
  auto o = tinyOptions();
  o.surfels = 2048;
  o.links = 48;
  o.rays = 256;
  o.lightmap_resolution = 32;
  o.grid = precompute::GridMode::kOn;
  out.baked = Baked::make(std::move(scene), o);
  if (!out.baked) return out;
  relight::Relighter r = out.baked->relighter();
  auto res = r.relight(set, {.max_bounces = 3, .emitter_samples = 64});
  EXPECT_TRUE(res) << res.status().toString();
  if (res) out.result = std::move(res).value();
  return out;
}

// Per lightmap cache (valid in both bakes) total irradiance, R channel, times s^2.
struct Compared {
  std::size_t caches = 0, over_1pct = 0;
  std::size_t push_flips = 0;  // caches valid, pushed or placed differently at the two scales
  double max_rel = 0.0, mean_rel = 0.0;
};

Compared compare(const ScaledBake& ref, const ScaledBake& other, bool indirect_only) {
  Compared c;
  const auto& la = ref.baked->p.lightmap;
  const auto& lb = other.baked->p.lightmap;
  EXPECT_EQ(la.size(), lb.size()) << "scale " << other.s << ": the cache layout changed";
  EXPECT_EQ(la.texel, lb.texel) << "scale " << other.s;
  if (la.size() != lb.size() || la.texel != lb.texel) return c;
  const double k = other.s * other.s;
  double peak = 0.0;
  std::vector<double> ea(la.size()), eb(la.size());
  for (std::size_t i = 0; i < la.size(); ++i) {
    const glm::vec3 a = indirect_only ? shIrradiance(ref.result.lightmap_sh.data() + la.texel[i] * 3 * std::size_t(ref.result.coeffCount()), ref.result.bands, la.normal[i])
                                      : cacheIrradiance(ref.result, la, i);
    const glm::vec3 b = indirect_only ? shIrradiance(other.result.lightmap_sh.data() + lb.texel[i] * 3 * std::size_t(other.result.coeffCount()), other.result.bands, lb.normal[i])
                                      : cacheIrradiance(other.result, lb, i);
    ea[i] = a.x, eb[i] = double(b.x) * k;
    peak = std::max(peak, ea[i]);
  }
  for (std::size_t i = 0; i < la.size(); ++i) {
    // A texel whose footprint holds a contact line (the foot of a block) sits on the validity
    // test's knife edge: rounding of the scaled coordinates decides whether its cache is
    // pushed, to which point of the footprint, or whether none is valid. Such flips are
    // counted and bounded, not compared.
    const bool moved_apart = glm::length(la.position[i] - lb.position[i] / float(other.s)) > 1e-4f;
    if (la.valid[i] != lb.valid[i] || la.pushed[i] != lb.pushed[i] || (la.pushed[i] && moved_apart)) {
      ++c.push_flips;
      continue;
    }
    if (!la.valid[i]) continue;
    // Relative to the cache's own value, with a floor of 1e-3 of the peak so dark corners
    // (a few lux of a thousand) do not turn rounding into large ratios.
    const double rel = std::abs(eb[i] - ea[i]) / std::max(ea[i], 1e-3 * peak);
    ++c.caches;
    c.mean_rel += rel;
    c.max_rel = std::max(c.max_rel, rel);
    c.over_1pct += rel > 0.01;
  }
  if (c.caches) c.mean_rel /= double(c.caches);
  return c;
}

TEST(StabilityScale, MillimetreAndKilometreCornellBoxesObeyTheInverseSquareLaw) {
  const ScaledBake one = bakeAtScale(1.0);
  ASSERT_TRUE(one.baked);
  ASSERT_FALSE(one.result.lightmap_sh.empty());
  for (double s : {1e-3, 1e3}) {
    const ScaledBake other = bakeAtScale(s);
    ASSERT_TRUE(other.baked) << "scale " << s;
    EXPECT_EQ(countBadValues(other.result, "scale " + std::to_string(s)), 0u);
    EXPECT_EQ(other.baked->p.surfels.size(), one.baked->p.surfels.size());
    for (bool indirect : {false, true}) {
      const Compared c = compare(one, other, indirect);
      ASSERT_GT(c.caches, 100u);
      // Bound: mean <= 0.1 % (measured 0.02 % at 1e-3, 0.09 % at 1e3); per cache 8 % of
      // E_1 / s^2: rounding of the scaled coordinates moves a few link rays between owners
      // (0.4 % at 1e-3) and, with the footprint search of the cache placement, flips which
      // point of a contact texel's footprint passes validity (3 of 434 caches at 1e-3, 5 of
      // 432 at 1e3); those flips are counted, at most 1.5 % of the caches, and not compared,
      // but the surfels their links see move too, so a neighbour reads up to 5.8 % off.
      EXPECT_LE(c.mean_rel, 0.001) << "scale " << s << (indirect ? " indirect" : " total");
      EXPECT_LE(c.max_rel, 0.08) << "scale " << s << (indirect ? " indirect" : " total");
      EXPECT_LE(double(c.push_flips), 0.015 * double(c.caches)) << "scale " << s;
      std::printf("scale %g %s: %zu caches, mean rel %.2e, max rel %.2e, %zu push flips\n", s,
                  indirect ? "indirect" : "total", c.caches, c.mean_rel, c.max_rel, c.push_flips);
    }
    // Grid caches (all light), L00 per channel.
    const auto& ga = one.result.grid_sh;
    const auto& gb = other.result.grid_sh;
    ASSERT_EQ(ga.size(), gb.size());
    const std::size_t stride = 3 * std::size_t(one.result.coeffCount());
    double peak = 0.0;
    for (std::size_t g = 0; g < ga.size(); g += stride) peak = std::max(peak, double(ga[g]));
    for (std::size_t g = 0; g < ga.size(); g += stride) {
      const double a = ga[g], b = double(gb[g]) * s * s;
      EXPECT_NEAR(b, a, 0.02 * std::max(a, 0.05 * peak)) << "grid cache " << g / stride << " at scale " << s;
    }
  }
}

}  // namespace
}  // namespace lightlink::stability
