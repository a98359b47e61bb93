// The direct layer (precompute::PrecomputeOptions::direct_scale, core/relight/direct_layer.h):
// baked direct light on a texel atlas finer than the indirect caches. It must follow a shadow
// edge more closely than the caches' texels do, keep the same energy, reuse unchanged lights
// exactly, survive the artifact, and give the same bits on any thread count.
#include <cmath>
#include <cstring>
#include <filesystem>
#include <random>

#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include "core/relight/direct_layer.h"
#include "core/scene/light_eval.h"
#include "tests/relight/relight_fixture.h"

namespace lightlink::relight {
namespace {

using namespace lightlink::relight::testing;

// A 4 m floor (y = 0) under an opaque 1.2 m square at y = 0.5, lit by a point light whose
// shadow edge runs across the floor at no texel-aligned angle.
scene::Scene blockerScene() {
  scene::Scene s;
  const int floor = addMaterial(s, glm::vec3(0.5f));
  const int blocker = addMaterial(s, glm::vec3(0.5f));
  s.materials[blocker].double_sided = true;
  addQuad(s, {-2, 0, -2}, {-2, 0, 2}, {2, 0, 2}, {2, 0, -2}, floor);
  addQuad(s, {-0.6f, 0.5f, -0.6f}, {-0.6f, 0.5f, 0.6f}, {0.6f, 0.5f, 0.6f}, {0.6f, 0.5f, -0.6f}, blocker);
  return s;
}

LightSet lamps(glm::vec3 second = {-1.2f, 1.5f, 0.9f}) {
  LightSet l;
  scene::Light a;
  a.position = {0.37f, 2.0f, 0.21f};
  a.intensity = 10.0f;
  scene::Light b = a;
  b.position = second;
  b.intensity = 4.0f;
  EXPECT_TRUE(l.add({"a", a, true}));
  EXPECT_TRUE(l.add({"b", b, true}));
  return l;
}

std::unique_ptr<Baked> bake(int direct_scale) {
  auto o = smallOptions();
  o.direct_scale = direct_scale;
  return Baked::make(blockerScene(), o);
}

// Bilinear lookup of the direct layer at lightmap UV uv over its valid texels, as an engine
// samples it.
glm::vec3 sampleDirect(const RelightResult& r, glm::vec2 uv) {
  const int w = r.direct_width, h = r.direct_height;
  const auto& valid = r.directIsFiner() ? r.direct_valid : r.texel_valid;
  const float fx = uv.x * float(w) - 0.5f, fy = uv.y * float(h) - 0.5f;
  const int x0 = int(std::floor(fx)), y0 = int(std::floor(fy));
  glm::vec3 sum(0.0f);
  float wsum = 0.0f;
  for (int dy = 0; dy < 2; ++dy)
    for (int dx = 0; dx < 2; ++dx) {
      const int x = std::clamp(x0 + dx, 0, w - 1), y = std::clamp(y0 + dy, 0, h - 1);
      const std::size_t t = std::size_t(y) * w + x;
      const float wt = (dx ? fx - x0 : 1 - (fx - x0)) * (dy ? fy - y0 : 1 - (fy - y0)) * float(valid[t]);
      sum += wt * r.direct[t];
      wsum += wt;
    }
  return wsum > 0.0f ? sum / wsum : glm::vec3(0.0f);
}

struct EdgeError {
  double mean_abs = 0.0, mean_truth = 0.0, mean_baked = 0.0;
};

// Random points on the floor (away from its rim): the baked direct looked up at their UV
// against the exact shadowed irradiance of the lights.
EdgeError floorError(const Baked& b, const RelightResult& r, const LightSet& lights) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> u01(0.0f, 1.0f);
  EdgeError e;
  int n = 0;
  for (const auto& mesh : b.scene.meshes) {
    for (std::size_t tri = 0; tri < mesh.triangleCount(); ++tri) {
      const std::uint32_t i0 = mesh.indices[3 * tri], i1 = mesh.indices[3 * tri + 1], i2 = mesh.indices[3 * tri + 2];
      const glm::vec3 p0 = mesh.positions[i0], p1 = mesh.positions[i1], p2 = mesh.positions[i2];
      if (std::abs(p0.y) > 1e-4f || std::abs(p1.y) > 1e-4f || std::abs(p2.y) > 1e-4f) continue;
      for (int k = 0; k < 3000; ++k) {
        float a = u01(rng), c = u01(rng);
        if (a + c > 1.0f) a = 1.0f - a, c = 1.0f - c;
        const glm::vec3 p = p0 + a * (p1 - p0) + c * (p2 - p0);
        if (std::abs(p.x) > 1.8f || std::abs(p.z) > 1.8f) continue;
        const glm::vec2 uv = mesh.uv1[i0] + a * (mesh.uv1[i1] - mesh.uv1[i0]) + c * (mesh.uv1[i2] - mesh.uv1[i0]);
        double truth = 0.0;
        for (const LightEntry& l : lights.lights()) {
          rt::Ray ray;
          ray.origin = b.accel->offsetOrigin(p, {0, 1, 0}, l.light.position - p);
          ray.dir = l.light.position - ray.origin;
          ray.tfar = 0.999f;
          if (!b.accel->occluded(ray)) truth += scene::irradianceFrom(l.light, p, {0, 1, 0}).x;
        }
        const double baked = sampleDirect(r, uv).x;
        e.mean_abs += std::abs(baked - truth);
        e.mean_truth += truth;
        e.mean_baked += baked;
        ++n;
      }
    }
  }
  EXPECT_GT(n, 1000);
  e.mean_abs /= n, e.mean_truth /= n, e.mean_baked /= n;
  return e;
}

TEST(DirectLayer, FollowsShadowEdgesMoreCloselyThanTheCachesWithTheSameEnergy) {
  auto coarse = bake(1), fine = bake(4);
  ASSERT_TRUE(coarse && fine);
  EXPECT_FALSE(coarse->p.hasDirectLayer());
  ASSERT_TRUE(fine->p.hasDirectLayer());
  EXPECT_EQ(fine->p.direct_texels.width, 4 * fine->p.lightmap.width);
  EXPECT_EQ(fine->p.direct_texels.height, 4 * fine->p.lightmap.height);
  const LightSet lights = lamps();
  Relighter rc = coarse->relighter(), rf = fine->relighter();
  auto c = rc.relight(lights, {.max_bounces = 0});
  auto f = rf.relight(lights, {.max_bounces = 0});
  ASSERT_TRUE(c && f);
  EXPECT_FALSE(c->directIsFiner());
  ASSERT_TRUE(f->directIsFiner());
  EXPECT_EQ(f->direct.size(), std::size_t(f->direct_width) * f->direct_height);
  // The indirect is the caches' either way: the same lightmap SH.
  EXPECT_EQ(c->lightmap_sh, f->lightmap_sh);
  const EdgeError ec = floorError(*coarse, *c, lights), ef = floorError(*fine, *f, lights);
  // Measured: mean |error| 4.9 % of the mean irradiance on the 32² caches, 1.6 % 4x finer.
  EXPECT_LT(ef.mean_abs, 0.5 * ec.mean_abs) << "coarse " << ec.mean_abs / ec.mean_truth << ", fine "
                                            << ef.mean_abs / ef.mean_truth;
  EXPECT_NEAR(ef.mean_baked, ef.mean_truth, 0.03 * ef.mean_truth);
  EXPECT_NEAR(ec.mean_baked, ec.mean_truth, 0.05 * ec.mean_truth);
  // Shadow edges are anti-aliased: texels straddling the edge hold a fraction of the light
  // (point-sampled texels are all or nothing, a staircase under bilinear filtering).
  {
    LightSet one;
    ASSERT_TRUE(one.add(lights.lights()[0]));
    auto r1 = rf.relight(one, {.max_bounces = 0});
    ASSERT_TRUE(r1);
    const auto& dt = fine->p.direct_texels;
    int partial = 0;
    for (std::size_t k = 0; k < dt.size(); ++k) {
      if (!dt.valid[k] || dt.position[k].y > 1e-3f) continue;
      const float full = scene::irradianceFrom(one.lights()[0].light, dt.position[k], dt.normal[k]).x;
      const float ratio = r1->direct[dt.texel[k]].x / full;
      partial += ratio > 0.2f && ratio < 0.8f;
    }
    EXPECT_GT(partial, 20);
  }
  // The wire's lightmap-size direct is the layer box-filtered: same energy as the coarse one.
  std::vector<glm::vec3> boxed;
  directAtLightmapSize(*f, boxed);
  ASSERT_EQ(boxed.size(), c->direct.size());
  double sb = 0.0, sc = 0.0;
  for (std::size_t t = 0; t < boxed.size(); ++t) sb += boxed[t].x, sc += c->direct[t].x;
  EXPECT_NEAR(sb, sc, 0.05 * sc);
}

TEST(DirectLayer, RetracesOnlyTheLightThatChangedAndMatchesAFreshRelight) {
  auto fine = bake(2);
  ASSERT_TRUE(fine);
  Relighter kept = fine->relighter();
  auto first = kept.relight(lamps(), {.max_bounces = 0});
  ASSERT_TRUE(first);
  EXPECT_EQ(first->passes.baked_direct, 2);
  const LightSet moved = lamps({-0.9f, 1.4f, 1.1f});
  auto second = kept.relight(moved, {.max_bounces = 0});
  ASSERT_TRUE(second);
  EXPECT_EQ(second->passes.baked_direct, 1);  // light "a" reused
  Relighter fresh = fine->relighter();
  auto want = fresh.relight(moved, {.max_bounces = 0});
  ASSERT_TRUE(want);
  ASSERT_EQ(second->direct.size(), want->direct.size());
  EXPECT_EQ(0, std::memcmp(second->direct.data(), want->direct.data(), want->direct.size() * sizeof(glm::vec3)));
}

TEST(DirectLayer, SameBitsOnAnyThreadCountAndAfterTheArtifact) {
  auto fine = bake(3);
  ASSERT_TRUE(fine);
  std::vector<glm::vec3> one, two;
  for (int threads : {1, 2}) {
    tbb::global_control c(tbb::global_control::max_allowed_parallelism, threads);
    Relighter r = fine->relighter();
    auto res = r.relight(lamps(), {.max_bounces = 1});
    ASSERT_TRUE(res);
    (threads == 1 ? one : two) = res->direct;
  }
  ASSERT_EQ(one.size(), two.size());
  EXPECT_EQ(0, std::memcmp(one.data(), two.data(), one.size() * sizeof(glm::vec3)));

  const auto path = std::filesystem::temp_directory_path() / "lightlink_direct_layer_test.llk";
  ASSERT_TRUE(precompute::save(fine->p, path.string(), 42));
  auto loaded = precompute::open(path.string());
  std::filesystem::remove(path);
  ASSERT_TRUE(loaded) << loaded.status().toString();
  ASSERT_TRUE(loaded->p.hasDirectLayer());
  EXPECT_EQ(loaded->p.direct_texels.width, fine->p.direct_texels.width);
  auto r = Relighter::create(fine->scene, *fine->accel, loaded->p, loaded->lightmap_links, loaded->grid_links);
  ASSERT_TRUE(r);
  auto res = r->relight(lamps(), {.max_bounces = 1});
  ASSERT_TRUE(res);
  ASSERT_EQ(res->direct.size(), one.size());
  EXPECT_EQ(0, std::memcmp(res->direct.data(), one.data(), one.size() * sizeof(glm::vec3)));
}

TEST(DirectLayer, ScaleIsValidatedAndLoweredToFitTheTexelLimit) {
  auto o = smallOptions();
  o.direct_scale = 9;
  EXPECT_FALSE(o.validate());
  o.direct_scale = 0;
  EXPECT_FALSE(o.validate());
  o.direct_scale = 8;
  o.limits.max_texels = 32 * 32 * 16;  // room for 4x, not 8x
  auto b = Baked::make(blockerScene(), o);
  ASSERT_TRUE(b);
  EXPECT_EQ(b->p.direct_texels.width, 4 * b->p.lightmap.width);
  bool warned = false;
  for (const auto& w : b->p.warnings) warned |= w.find("direct scale 8 lowered to 4") != std::string::npos;
  EXPECT_TRUE(warned);
}

}  // namespace
}  // namespace lightlink::relight
