// PreviewGrid (core/preview): the instant preview's grid against the linked grid of the same
// scene, determinism across thread counts, zero light, NaN-freedom and bad input.
#include <cmath>
#include <cstring>
#include <memory>
#include <optional>

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include "core/precompute/precompute.h"
#include "core/preview/preview_grid.h"
#include "core/relight/relight.h"
#include "core/rt/accel.h"
#include "core/scene/load.h"
#include "core/sh/sh.h"
#include "tests/common/testing.h"

namespace lightlink::preview {
namespace {

using lightlink::testing::sourceDir;

// The demo Cornell box (a point light and an emissive ceiling panel), precomputed once with a
// grid of 0.1 m spacing: the linked reference every test here compares with.
struct Cornell {
  scene::Scene scene;
  std::optional<rt::Accel> accel;
  precompute::Precomputation p;
  relight::LightSet lights;

  static const Cornell& get() {
    static const std::unique_ptr<Cornell> c = [] {
      auto c = std::make_unique<Cornell>();
      auto s = scene::loadScene((sourceDir() / "clients/demo/cornell_box.gltf").string());
      EXPECT_TRUE(s) << s.status().message();
      c->scene = std::move(s).value();
      auto o = precompute::preset("draft");
      EXPECT_TRUE(o);
      o->surfels = 8192;
      o->links = 128;
      o->rays = 1024;
      o->grid = precompute::GridMode::kOn;
      o->grid_spacing_m = 0.1f;
      auto p = precompute::run(c->scene, *o);
      EXPECT_TRUE(p) << p.status().message();
      c->p = std::move(p).value();
      auto a = rt::Accel::build(c->scene);
      EXPECT_TRUE(a) << a.status().message();
      c->accel.emplace(std::move(a).value());
      c->lights = relight::LightSet::fromSceneLights(c->scene.lights);
      return c;
    }();
    return *c;
  }

  PreviewOptions options(int bounces = 3) const {
    PreviewOptions o;
    o.grid.spacing_m = p.options.grid_spacing_m;
    o.grid.resolution = p.options.grid_resolution;
    o.grid.validity.rays = p.options.validity_rays;
    o.bands = p.options.bands;
    o.bounces = bounces;
    return o;
  }

  std::vector<float> linkedGrid(int bounces) const {
    auto r = relight::Relighter::create(scene, *accel, p);
    EXPECT_TRUE(r) << r.status().message();
    relight::RelightOptions o;
    o.max_bounces = bounces;
    auto result = r->relight(lights, o);
    EXPECT_TRUE(result) << result.status().message();
    return result->grid_sh;
  }
};

// Irradiance error of a grid against a reference grid: over the probes both call valid, the
// irradiance (R+G+B) on the six axis normals; RMSE relative to the reference's mean.
struct GridError {
  double rel_rmse = 0.0, mean_ref = 0.0, mean_got = 0.0;
  std::size_t samples = 0;
};
GridError compare(const std::vector<float>& got, const std::vector<float>& ref, const std::vector<std::uint8_t>& valid,
                  int bands) {
  const std::size_t nc = std::size_t(bands) * bands, st = 3 * nc;
  const glm::vec3 axes[6] = {{1, 0, 0}, {-1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}, {0, 0, -1}};
  double se = 0.0, sum_ref = 0.0, sum_got = 0.0;
  GridError e;
  for (std::size_t p = 0; p < valid.size(); ++p) {
    if (!valid[p]) continue;
    for (const auto& n : axes) {
      double g = 0.0, r = 0.0;
      for (int c = 0; c < 3; ++c) {
        g += sh::irradiance(bands, got.data() + p * st + c * nc, n);
        r += sh::irradiance(bands, ref.data() + p * st + c * nc, n);
      }
      se += (g - r) * (g - r);
      sum_ref += r;
      sum_got += g;
      ++e.samples;
    }
  }
  e.mean_ref = sum_ref / double(e.samples);
  e.mean_got = sum_got / double(e.samples);
  e.rel_rmse = std::sqrt(se / double(e.samples)) / e.mean_ref;
  return e;
}

TEST(PreviewGrid, PlacesTheLinkedGrid) {
  const Cornell& c = Cornell::get();
  auto g = PreviewGrid::build(c.scene, *c.accel, c.options());
  ASSERT_TRUE(g) << g.status().message();
  EXPECT_EQ(g->grid().dims, c.p.grid.dims);
  EXPECT_EQ(g->grid().origin, c.p.grid.origin);
  EXPECT_EQ(g->grid().spacing_m, c.p.grid.spacing_m);
  EXPECT_EQ(g->grid().valid, c.p.grid.valid);
  EXPECT_EQ(g->bands(), c.p.options.bands);
}

// The accuracy the docs state (docs/service.md "Preview while the precompute runs"): one
// bounce against the linked grid with bounces off (the same transport), and the preview's
// default (three Radiance Hints grid bounces) against the converged linked grid.
TEST(PreviewGrid, CloseToTheLinkedGrid) {
  const Cornell& c = Cornell::get();
  std::vector<float> preview;
  for (const int bounces : {0, 3}) {
    auto g = PreviewGrid::build(c.scene, *c.accel, c.options(bounces));
    ASSERT_TRUE(g) << g.status().message();
    PreviewStats st;
    ASSERT_TRUE(g->light(c.lights, preview, &st));
    const auto linked = c.linkedGrid(bounces == 0 ? 0 : 100);
    const GridError e = compare(preview, linked, c.p.grid.valid, c.p.options.bands);
    std::printf("[ preview ] Cornell %zu probes x %d rays, grid bounces %d vs linked %s: rel. RMSE %.3f, mean %.4g vs %.4g "
                "(build %.1f ms, light %.1f ms)\n",
                st.probes_valid, st.rays_per_probe, bounces, bounces == 0 ? "without bounces" : "converged",
                e.rel_rmse, e.mean_got, e.mean_ref, 1e3 * (st.place_seconds + st.trace_seconds), 1e3 * st.light_seconds);
    // Measured (this test's output, docs/service.md): rel. RMSE 0.153 and mean -3.8 % without
    // bounces, 0.107 and -2.8 % with three grid bounces against the converged linked grid
    // (256 rays per probe). The bounds leave room for other rounding, not for a different
    // estimator.
    EXPECT_LT(e.rel_rmse, bounces == 0 ? 0.23 : 0.16);
    EXPECT_NEAR(e.mean_got / e.mean_ref, 1.0, 0.08);
  }
}

TEST(PreviewGrid, BitIdenticalForAnyThreadCount) {
  const Cornell& c = Cornell::get();
  std::vector<float> out[2];
  for (int i = 0; i < 2; ++i) {
    tbb::global_control threads(tbb::global_control::max_allowed_parallelism, i == 0 ? 1 : 4);
    auto g = PreviewGrid::build(c.scene, *c.accel, c.options());
    ASSERT_TRUE(g) << g.status().message();
    ASSERT_TRUE(g->light(c.lights, out[i]));
  }
  ASSERT_EQ(out[0].size(), out[1].size());
  EXPECT_EQ(std::memcmp(out[0].data(), out[1].data(), out[0].size() * sizeof(float)), 0);
}

TEST(PreviewGrid, NoLightGivesZeroAndNothingIsNaN) {
  const Cornell& c = Cornell::get();
  auto g = PreviewGrid::build(c.scene, *c.accel, c.options());
  ASSERT_TRUE(g) << g.status().message();
  // No punctual light, every emissive material scaled to 0, no sky.
  relight::LightSet dark;
  for (std::size_t m = 0; m < c.scene.materials.size(); ++m)
    ASSERT_TRUE(dark.setEmissive({int(m), relight::EmissiveOverride::Mode::kScale, glm::vec3(0.0f)}));
  std::vector<float> sh;
  ASSERT_TRUE(g->light(dark, sh));
  ASSERT_EQ(sh.size(), c.p.grid.size() * 3 * std::size_t(c.p.options.bands * c.p.options.bands));
  for (float v : sh) ASSERT_EQ(v, 0.0f);
  // A sky and the scene's lights: finite everywhere, and more light than none.
  relight::LightSet lit = c.lights;
  relight::Sky sky;
  sky.radiance = glm::vec3(0.5f, 0.6f, 1.0f);
  ASSERT_TRUE(lit.setSky(sky));
  ASSERT_TRUE(g->light(lit, sh));
  double sum = 0.0;
  for (float v : sh) {
    ASSERT_TRUE(std::isfinite(v));
    sum += v;
  }
  EXPECT_GT(sum, 0.0);
}

TEST(PreviewGrid, RelightsALightChange) {
  const Cornell& c = Cornell::get();
  auto g = PreviewGrid::build(c.scene, *c.accel, c.options());
  ASSERT_TRUE(g) << g.status().message();
  std::vector<float> before, after;
  ASSERT_TRUE(g->light(c.lights, before));
  relight::LightSet brighter = c.lights;
  ASSERT_FALSE(brighter.lights().empty());
  relight::LightEntry e = brighter.lights().front();
  e.light.intensity *= 4.0f;
  ASSERT_TRUE(brighter.modify(e));
  ASSERT_TRUE(g->light(brighter, after));
  double s0 = 0.0, s1 = 0.0;
  for (std::size_t i = 0; i < before.size(); i += 3 * std::size_t(g->bands() * g->bands())) s0 += before[i], s1 += after[i];
  EXPECT_GT(s1, 1.5 * s0);
}

TEST(PreviewGrid, BadInputIsAnErrorNamingIt) {
  const Cornell& c = Cornell::get();
  PreviewOptions o = c.options();
  o.rays = 2;
  auto bad = PreviewGrid::build(c.scene, *c.accel, o);
  ASSERT_FALSE(bad);
  EXPECT_NE(bad.status().message().find("rays"), std::string::npos) << bad.status().message();
  o = c.options();
  o.bands = 5;
  bad = PreviewGrid::build(c.scene, *c.accel, o);
  ASSERT_FALSE(bad);
  EXPECT_NE(bad.status().message().find("bands"), std::string::npos) << bad.status().message();
  auto g = PreviewGrid::build(c.scene, *c.accel, c.options());
  ASSERT_TRUE(g) << g.status().message();
  relight::LightSet foreign;
  ASSERT_TRUE(foreign.setEmissive({int(c.scene.materials.size()) + 3, relight::EmissiveOverride::Mode::kScale,
                                   glm::vec3(2.0f)}));
  std::vector<float> sh;
  const Status s = g->light(foreign, sh);
  ASSERT_FALSE(s);
  EXPECT_NE(s.message().find("material"), std::string::npos) << s.message();
}

}  // namespace
}  // namespace lightlink::preview
