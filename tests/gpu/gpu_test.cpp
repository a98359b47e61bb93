// GPU relight vs the CPU reference (docs/gpu.md "Tolerances").
//
// Parity: both backends get the same surfel irradiance (RelightOptions::surfel_irradiance),
// so everything downstream (emission, pull, node radiosity, cache lighting with sky, bounces,
// fill, texels, dilation) must agree up to fp32 summation order. Shadows: the Cornell box
// with its own point light, shadow maps against ray-traced shadows, a measured and bounded
// difference. Small precomputations keep llvmpipe fast.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>

#include <nlohmann/json.hpp>

#include "core/precompute/precompute.h"
#include "core/relight/backend.h"
#include "core/scene/load.h"
#include "gpu/backend_factory.h"
#include "gpu/gl_objects.h"
#include "gpu/gpu_relight.h"
#include "tests/common/testing.h"
#include "tests/gpu/gpu_testing.h"

namespace lightlink::gpu {
namespace {

const std::string kDemo = (testing::sourceDir() / "clients/demo/cornell_box.gltf").string();

#define ASSERT_OK(expr)                                  \
  do {                                                   \
    const Status st_ = (expr);                           \
    ASSERT_TRUE(st_.isOk()) << #expr << ": " << st_.toString(); \
  } while (0)

struct Fixture {
  scene::Scene scene;
  precompute::Precomputation p;
  std::unique_ptr<rt::Accel> accel;
};

// The demo scene at a small precomputation, grid on (the box has a dynamic object).
const Fixture& demo() {
  static Fixture* f = [] {
    auto* fx = new Fixture;
    auto s = scene::loadGltf(kDemo);
    EXPECT_TRUE(s) << s.status().toString();
    fx->scene = std::move(*s);
    precompute::PrecomputeOptions o;
    o.surfels = 1500;
    o.links = 48;
    o.rays = 256;
    o.target_resolution = 32;
    o.grid = precompute::GridMode::kOn;
    o.grid_resolution = 5;
    o.validity_rays = 16;
    auto p = precompute::run(fx->scene, o);
    EXPECT_TRUE(p) << p.status().toString();
    fx->p = std::move(*p);
    auto a = rt::Accel::build(fx->scene);
    EXPECT_TRUE(a) << a.status().toString();
    fx->accel = std::make_unique<rt::Accel>(std::move(*a));
    return fx;
  }();
  return *f;
}

// sqrt(sum (a - b)^2 / sum b^2) over all floats.
double relRms(std::span<const float> a, std::span<const float> b) {
  EXPECT_EQ(a.size(), b.size());
  double num = 0.0, den = 0.0;
  for (std::size_t i = 0; i < std::min(a.size(), b.size()); ++i) {
    num += double(a[i] - b[i]) * (a[i] - b[i]);
    den += double(b[i]) * b[i];
  }
  return den > 0.0 ? std::sqrt(num / den) : std::sqrt(num);
}
std::span<const float> floats(const std::vector<glm::vec3>& v) {
  return {reinterpret_cast<const float*>(v.data()), 3 * v.size()};
}

// Largest |a - b| relative to the largest |b| (a pointwise bound the RMS could hide).
double relMax(std::span<const float> a, std::span<const float> b) {
  double m = 0.0, scale = 0.0;
  for (std::size_t i = 0; i < std::min(a.size(), b.size()); ++i) {
    m = std::max(m, double(std::abs(a[i] - b[i])));
    scale = std::max(scale, double(std::abs(b[i])));
  }
  return scale > 0.0 ? m / scale : m;
}

TEST(GpuContext, ProbeFindsAContext) {
  REQUIRE_GPU();
  const GpuProbe& probe = probeGpu();
  EXPECT_FALSE(probe.renderer.empty());
  EXPECT_NE(probe.version.find("4."), std::string::npos) << probe.version;
  std::printf("GPU: %s, %s\n", probe.renderer.c_str(), probe.version.c_str());
}

TEST(GpuShaders, CompileErrorNamesTheShaderAndCarriesTheLog) {
  REQUIRE_GPU();
  auto ctx = GlContext::create();
  ASSERT_TRUE(ctx) << ctx.status().toString();
  GlContext::Current cur(**ctx);
  ASSERT_TRUE(cur.status()) << cur.status().toString();
  auto bad = GlProgram::computeFromSource("broken_stage.comp",
                                          "#version 450\nlayout(local_size_x = 1) in;\n"
                                          "void main() { no_such_variable = 1.0; }\n");
  ASSERT_FALSE(bad);
  EXPECT_NE(bad.status().message().find("broken_stage.comp"), std::string::npos) << bad.status().message();
  EXPECT_NE(bad.status().message().find("no_such_variable"), std::string::npos) << bad.status().message();
  auto missing = GlProgram::computeFromSource("includes_missing.comp", "#version 450\n#include \"nope.glsl\"\n");
  ASSERT_FALSE(missing);
  EXPECT_NE(missing.status().message().find("nope.glsl"), std::string::npos) << missing.status().message();
  auto unknown = GlProgram::compute("not_a_shader.comp");
  ASSERT_FALSE(unknown);
  EXPECT_NE(unknown.status().message().find("not_a_shader.comp"), std::string::npos);
}

TEST(GpuBackend, FactoryNamesTheBackendThatRan) {
  REQUIRE_GPU();
  const Fixture& f = demo();
  std::string note;
  auto gpu = makeBackend(BackendChoice::kGpu, f.scene, *f.accel, f.p, f.p.lightmap_links.view(),
                         f.p.grid_links.view(), &note);
  ASSERT_TRUE(gpu) << gpu.status().toString();
  EXPECT_EQ((*gpu)->name(), "gpu");
  EXPECT_EQ(note.rfind("gpu: ", 0), 0u) << note;
  auto cpu = makeBackend(BackendChoice::kCpu, f.scene, *f.accel, f.p, f.p.lightmap_links.view(),
                         f.p.grid_links.view(), &note);
  ASSERT_TRUE(cpu);
  EXPECT_EQ((*cpu)->name(), "cpu");
  // auto: a hardware GPU, or the CPU when the only context is a software rasteriser.
  auto autob = makeBackend(BackendChoice::kAuto, f.scene, *f.accel, f.p, f.p.lightmap_links.view(),
                           f.p.grid_links.view(), &note);
  ASSERT_TRUE(autob);
  EXPECT_EQ((*autob)->name(), probeGpu().software ? "cpu" : "gpu") << note;
  if (probeGpu().software) {
    EXPECT_NE(note.find("software renderer"), std::string::npos) << note;
  }
  relight::RelightResult r;
  relight::RelightOptions o;
  o.max_bounces = 1;
  o.emitter_samples = 2;  // few: the relight only has to run
  ASSERT_OK((*gpu)->relightInto(relight::LightSet::fromSceneLights(f.scene.lights), o, r));
  EXPECT_EQ(r.backend, "gpu");
  // Bad options are rejected with the field named, as on the CPU.
  o.bands = 4;
  Status s = (*gpu)->relightInto(relight::LightSet::fromSceneLights(f.scene.lights), o, r);
  ASSERT_FALSE(s);
  EXPECT_NE(s.message().find("bands 4"), std::string::npos) << s.message();
  o.bands = 0;
  const std::vector<glm::vec3> wrong(3, glm::vec3(1.0f));
  o.surfel_irradiance = wrong;
  s = (*gpu)->relightInto(relight::LightSet::fromSceneLights(f.scene.lights), o, r);
  ASSERT_FALSE(s);
  EXPECT_NE(s.message().find("surfel_irradiance"), std::string::npos) << s.message();
}

// Same surfel irradiance on both backends; everything after it must agree to fp32 rounding.
void parity(relight::LinkForm form, int bands) {
  const Fixture& f = demo();
  auto cpu = relight::makeCpuBackend(f.scene, *f.accel, f.p, f.p.lightmap_links.view(), f.p.grid_links.view());
  ASSERT_TRUE(cpu) << cpu.status().toString();
  // The host samples the emitters for both backends, so the surfels' light is identical; the
  // GPU's own emitter sampling is compared in emitter_gpu_test.cpp.
  GpuOptions host_emitters;
  host_emitters.emitter_sampling = false;
  auto gpu = makeGpuBackend(f.scene, *f.accel, f.p, f.p.lightmap_links.view(), f.p.grid_links.view(), host_emitters);
  ASSERT_TRUE(gpu) << gpu.status().toString();
  // A smooth, non-trivial irradiance pattern over the surfels (lux).
  std::vector<glm::vec3> e(f.p.surfels.size());
  for (std::size_t s = 0; s < e.size(); ++s) {
    const glm::vec3 x = f.p.surfels.position[s] / f.scene.scale;
    e[s] = glm::vec3(2.0f + std::sin(7.0f * x.x), 1.5f + std::cos(5.0f * x.y), 1.0f + x.z * x.z) * 3.0f;
  }
  relight::LightSet lights = relight::LightSet::fromSceneLights(f.scene.lights);  // emitters + point light
  relight::Sky sky;
  sky.radiance = glm::vec3(0.2f, 0.3f, 0.5f);
  ASSERT_OK(lights.setSky(sky));
  const relight::LightSet scene_lights = relight::LightSet::fromSceneLights(f.scene.lights);
  for (const auto& l : scene_lights.lights()) {
    relight::LightEntry realtime = l;  // not baked: no shadowed direct per texel (shadows differ)
    realtime.baked = false;
    ASSERT_OK(lights.modify(realtime));
  }
  relight::RelightOptions o;
  o.link_form = form;
  o.bands = bands;
  o.max_bounces = 4;
  o.bounce_threshold = 0.0f;  // same bounce count on both
  o.emitter_samples = 4;
  o.surfel_irradiance = e;
  o.smooth_indirect = form == relight::LinkForm::kRuntime;  // both backends filter their texels alike
  relight::RelightResult rc, rg;
  ASSERT_OK((*cpu)->relightInto(lights, o, rc));
  ASSERT_OK((*gpu)->relightInto(lights, o, rg));
  EXPECT_EQ(rg.backend, "gpu");
  ASSERT_EQ(rc.bounce_log.size(), rg.bounce_log.size());
  EXPECT_GT(rc.passes.emission, 0);
  EXPECT_GT(rc.passes.grid_lighting, 0);
  EXPECT_GT(rc.passes.sky, 0);
  // The emitters' grid SH (host sampling on both backends here) is part of the compared grid.
  EXPECT_EQ(rc.passes.grid_emitter, 1);
  EXPECT_EQ(rg.passes.grid_emitter, 1);
  EXPECT_EQ(rc.texel_valid, rg.texel_valid);
  const double lm = relRms(rg.lightmap_sh, rc.lightmap_sh), lm_max = relMax(rg.lightmap_sh, rc.lightmap_sh);
  const double grid = relRms(rg.grid_sh, rc.grid_sh);
  const double surf = relRms(floats(rg.surfel_radiosity), floats(rc.surfel_radiosity));
  const double dir = relRms(floats(rg.direct), floats(rc.direct));
  std::printf("parity %s bands %d: lightmap rel RMS %.2e (max %.2e), grid %.2e, surfels %.2e, direct %.2e\n",
              form == relight::LinkForm::kProjected ? "projected" : "runtime", bands, lm, lm_max, grid, surf, dir);
  // fp32 sums in another order (and, runtime form, another evaluation of the cap basis):
  // documented tolerance 1e-4 relative RMS, 1e-3 pointwise relative to the largest value.
  EXPECT_LT(lm, 1e-4);
  EXPECT_LT(lm_max, 1e-3);
  EXPECT_LT(grid, 1e-4);
  EXPECT_LT(surf, 1e-4);
  EXPECT_LT(dir, 1e-5);  // emitter direct: the same host sampling on both
  for (std::size_t k = 0; k < rc.bounce_log.size(); ++k)
    EXPECT_NEAR(rg.bounce_log[k].added_flux, rc.bounce_log[k].added_flux, 1e-3 * rc.bounce_log[k].total_flux);
}

TEST(GpuParity, ProjectedLinksGivenSurfelLight) {
  REQUIRE_GPU();
  parity(relight::LinkForm::kProjected, 0);
}

TEST(GpuParity, RuntimeLinksGivenSurfelLight) {
  REQUIRE_GPU();
  parity(relight::LinkForm::kRuntime, 3);
}

TEST(GpuParity, ProjectedLinksFewerBands) {
  REQUIRE_GPU();
  parity(relight::LinkForm::kProjected, 2);
}

// Shadow maps vs ray-traced shadows on the demo scene, its own baked point light: the
// difference is measured (printed) and bounded.
TEST(GpuShadows, ShadowMapsCloseToRayTracedOnCornellBox) {
  REQUIRE_GPU();
  const Fixture& f = demo();
  auto cpu = relight::makeCpuBackend(f.scene, *f.accel, f.p, f.p.lightmap_links.view(), f.p.grid_links.view());
  ASSERT_TRUE(cpu);
  auto gpu = makeGpuBackend(f.scene, *f.accel, f.p, f.p.lightmap_links.view(), f.p.grid_links.view());
  ASSERT_TRUE(gpu) << gpu.status().toString();
  relight::LightSet lights = relight::LightSet::fromSceneLights(f.scene.lights);
  ASSERT_OK(lights.setEmissiveBaked(false));  // direct = the point light's only
  relight::RelightOptions o;
  o.max_bounces = 2;
  relight::RelightResult rc, rg;
  ASSERT_OK((*cpu)->relightInto(lights, o, rc));
  ASSERT_OK((*gpu)->relightInto(lights, o, rg));
  ASSERT_GT(rg.passes.baked_direct, 0);
  const double direct = relRms(floats(rg.direct), floats(rc.direct));
  const double surf = relRms(floats(rg.surfel_radiosity), floats(rc.surfel_radiosity));
  const double lm = relRms(rg.lightmap_sh, rc.lightmap_sh);
  std::printf("shadow maps vs ray traced (Cornell box): direct rel RMS %.4f, surfels %.4f, indirect lightmap %.4f\n",
              direct, surf, lm);
  EXPECT_LT(direct, 0.10);
  EXPECT_LT(surf, 0.10);
  EXPECT_LT(lm, 0.05);
}

// Runs a shell command, returning (exit status, stdout + stderr).
std::pair<int, std::string> runCommand(const std::string& command) {
  std::string out;
  FILE* pipe = ::popen((command + " 2>&1").c_str(), "r");
  if (!pipe) return {-1, ""};
  char buf[4096];
  while (std::size_t n = std::fread(buf, 1, sizeof(buf), pipe)) out.append(buf, n);
  return {::pclose(pipe), out};
}

TEST(GpuBake, BackendOptionReachesTheReport) {
  REQUIRE_GPU();
  testing::TempDir dir;
  const std::string base = std::string(LIGHTLINK_CLI_PATH) + " bake " + kDemo + " -o " + (dir / "out").string() +
                           " --preset draft --bounces 1 -q --cache-dir " + (dir / "cache").string();
  auto [rc, out] = runCommand(base + " --backend gpu");
  ASSERT_EQ(rc, 0) << out;
  nlohmann::json report = nlohmann::json::parse(std::ifstream(dir / "out" / "report.json"));
  EXPECT_EQ(report["backend"]["used"], "gpu") << report["backend"].dump();
  EXPECT_EQ(report["relight"]["backend"], "gpu");
  std::tie(rc, out) = runCommand(base + " --backend cuda");
  EXPECT_NE(rc, 0);
  EXPECT_NE(out.find("--backend"), std::string::npos) << out;
}


// The GPU runs the one relight pipeline too: an unchanged light set rewrites only the texels
// from the kept GPU buffers and gives the same result; a changed one is a full relight.
TEST(GpuBackend, UnchangedLightSetRewritesOnlyTheTexels) {
  REQUIRE_GPU();
  const Fixture& f = demo();
  auto gpu = makeGpuBackend(f.scene, *f.accel, f.p, f.p.lightmap_links.view(), f.p.grid_links.view());
  ASSERT_TRUE(gpu) << gpu.status().toString();
  relight::LightSet lights = relight::LightSet::fromSceneLights(f.scene.lights);
  relight::RelightOptions o;
  o.max_bounces = 3;
  o.emitter_samples = 2;
  relight::RelightResult first, again;
  ASSERT_OK((*gpu)->relightInto(lights, o, first));
  EXPECT_EQ(first.passes.unchanged, 0);
  EXPECT_GT(first.passes.bounces, 0);
  ASSERT_OK((*gpu)->relightInto(lights, o, again));
  EXPECT_EQ(again.passes.unchanged, 1);
  EXPECT_EQ(again.passes.cache_lighting, 0);
  EXPECT_EQ(again.bounce_stop, first.bounce_stop);
  EXPECT_EQ(again.lightmap_sh, first.lightmap_sh);
  EXPECT_EQ(again.direct, first.direct);
  EXPECT_EQ(again.grid_sh, first.grid_sh);
  EXPECT_EQ(again.surfel_radiosity, first.surfel_radiosity);
  relight::LightEntry moved = lights.lights().front();
  moved.light.position += glm::vec3(0.05f, 0.0f, 0.0f) * f.scene.scale;
  ASSERT_OK(lights.modify(moved));
  ASSERT_OK((*gpu)->relightInto(lights, o, again));
  EXPECT_EQ(again.passes.unchanged, 0);
  EXPECT_EQ(again.passes.incremental, 0);  // the incremental path is the CPU's
  EXPECT_NE(again.lightmap_sh, first.lightmap_sh);
}

// Warm start on the GPU: b and the caches kept on the device start the next relight's bounce
// iteration, and warm relights of the same light set converge to the GPU's cold answer.
TEST(GpuBackend, WarmStartConvergesToTheColdAnswer) {
  REQUIRE_GPU();
  const Fixture& f = demo();
  auto gpu = makeGpuBackend(f.scene, *f.accel, f.p, f.p.lightmap_links.view(), f.p.grid_links.view());
  ASSERT_TRUE(gpu) << gpu.status().toString();
  relight::LightSet lights = relight::LightSet::fromSceneLights(f.scene.lights);
  relight::RelightOptions cold;
  cold.max_bounces = 100;
  cold.bounce_threshold = 1e-5f;
  cold.emitter_samples = 2;
  relight::RelightResult r, target;
  ASSERT_OK((*gpu)->relightInto(lights, cold, r));
  relight::LightEntry moved = lights.lights().front();
  moved.light.position += glm::vec3(0.05f, 0.0f, 0.0f) * f.scene.scale;
  ASSERT_OK(lights.modify(moved));
  relight::RelightOptions warm = cold;
  warm.max_bounces = 1;
  warm.bounce_threshold = 0.0f;
  warm.warm_start = true;
  double change = 1.0;
  for (int k = 0; k < 60 && change > 1e-5; ++k) {
    ASSERT_OK((*gpu)->relightInto(lights, warm, r));
    ASSERT_EQ(r.passes.warm, 1);
    ASSERT_EQ(r.bounce_log.size(), 1u);
    change = r.bounce_log[0].added_flux / r.bounce_log[0].total_flux;
  }
  EXPECT_LE(change, 1e-5);
  auto fresh = makeGpuBackend(f.scene, *f.accel, f.p, f.p.lightmap_links.view(), f.p.grid_links.view());
  ASSERT_TRUE(fresh);
  ASSERT_OK((*fresh)->relightInto(lights, cold, target));
  EXPECT_EQ(target.passes.warm, 0);
  EXPECT_LT(relRms(r.lightmap_sh, target.lightmap_sh), 1e-3);
  EXPECT_LT(relRms(r.grid_sh, target.grid_sh), 1e-3);
}

}  // namespace
}  // namespace lightlink::gpu
