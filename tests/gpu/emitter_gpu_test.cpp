// The emitters' sampled light on the GPU (gpu/emitter_sampling.h) against the host sampler
// (core/relight/emitter_direct.h), on Mesa llvmpipe in CI (docs/gpu.md "Tolerances").
//
// The same samples on both sides: directions agree to float precision, so a point differs
// only where one of its samples lands within rounding of a shadow edge. Compared per product
// (surfels, lightmap caches, grid SH) on the bundled Cornell box (ceiling emitter, two blocks)
// and on a plate that half shadows a floor from a lamp; two GPU runs must be bit-identical;
// alpha cut-outs and textured emission go back to the host, and the relight says so.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>

#include "core/precompute/precompute.h"
#include "core/relight/backend.h"
#include "core/relight/direct_points.h"
#include "core/relight/emitter_direct.h"
#include "core/relight/emitter_layers.h"
#include "core/relight/emission_state.h"
#include "core/scene/load.h"
#include "gpu/backend_factory.h"
#include "gpu/egl_context.h"
#include "gpu/emitter_sampling.h"
#include "gpu/gl_objects.h"
#include "tests/common/testing.h"
#include "tests/gpu/gpu_testing.h"

namespace lightlink::gpu {
namespace {

using relight::detail::EmitterReceivers;
using relight::detail::EmitterSampler;

struct Cornell {
  scene::Scene scene;
  precompute::Precomputation p;
  std::unique_ptr<rt::Accel> accel;
};

// The Cornell box at a small precomputation; direct_scale 2 adds a finer direct layer.
Cornell* makeCornell(int direct_scale) {
    auto* fx = new Cornell;
    auto s = scene::loadGltf((testing::sourceDir() / "clients/demo/cornell_box.gltf").string());
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
    o.direct_scale = direct_scale;
    auto p = precompute::run(fx->scene, o);
    EXPECT_TRUE(p) << p.status().toString();
    fx->p = std::move(*p);
    auto a = rt::Accel::build(fx->scene);
    EXPECT_TRUE(a) << a.status().toString();
    fx->accel = std::make_unique<rt::Accel>(std::move(*a));
    return fx;
}
const Cornell& cornell() {
  static Cornell* f = makeCornell(1);
  return *f;
}

// A context, timers and the GPU sampler for one scene.
struct Gpu {
  std::unique_ptr<GlContext> ctx;
  std::optional<GlContext::Current> current;
  std::unique_ptr<GpuEmitterSampling> sampling;
  Gpu(const scene::Scene& scene, const rt::Accel& accel) {
    auto c = GlContext::create();
    EXPECT_TRUE(c) << c.status().toString();
    if (!c) return;
    ctx = std::move(*c);
    current.emplace(*ctx);
    sampling = std::make_unique<GpuEmitterSampling>(scene, accel);
  }
  ~Gpu() { sampling.reset(); }  // GL objects go while the context is current
};

struct Compare {
  double rel_rms = 0.0;   // sqrt(sum (g - c)^2 / sum c^2)
  double differ = 0.0;    // fraction of points whose values differ by > 1e-3 of the largest value
  double zero = 0.0;      // fraction of points that get no light on the host (shadowed or invalid)
};
Compare compare(const std::vector<float>& gpu, const std::vector<float>& cpu, std::size_t stride) {
  Compare c;
  EXPECT_EQ(gpu.size(), cpu.size());
  double num = 0.0, den = 0.0, largest = 0.0;
  for (float v : cpu) largest = std::max(largest, double(std::abs(v)));
  const std::size_t points = cpu.size() / stride;
  std::size_t differ = 0, zero = 0;
  for (std::size_t p = 0; p < points && gpu.size() == cpu.size(); ++p) {
    bool d = false, z = true;
    for (std::size_t k = 0; k < stride; ++k) {
      const double a = gpu[p * stride + k], b = cpu[p * stride + k];
      num += (a - b) * (a - b), den += b * b;
      d = d || std::abs(a - b) > 1e-3 * largest;
      z = z && b == 0.0;
    }
    differ += d, zero += z;
  }
  c.rel_rms = den > 0.0 ? std::sqrt(num / den) : std::sqrt(num);
  c.differ = double(differ) / double(std::max<std::size_t>(points, 1));
  c.zero = double(zero) / double(std::max<std::size_t>(points, 1));
  return c;
}

template <class Seed>
std::vector<glm::vec2> rotations(std::size_t n, Seed seed) {
  std::vector<glm::vec2> r(n);
  for (std::size_t i = 0; i < n; ++i) r[i] = relight::detail::emitterRotation(seed(i));
  return r;
}

// The host's layers for irradiance at points, as EmissionState samples surfels.
std::vector<float> hostIrradiance(const EmitterSampler& sampler, std::span<const glm::vec3> position,
                                  std::span<const glm::vec3> normal, int samples, std::size_t& rays) {
  const std::size_t L = std::size_t(sampler.layerCount());
  std::vector<float> layers(position.size() * L * 3, 0.0f);
  EmitterSampler::Scratch scratch;
  for (std::size_t s = 0; s < position.size(); ++s)
    sampler.irradiance(position[s], normal[s], samples, relight::detail::surfelEmitterSeed(s), scratch,
                       reinterpret_cast<glm::vec3*>(layers.data() + s * L * 3), rays);
  return layers;
}

// Tolerances (docs/gpu.md): the same samples to rounding, so only a point with a sample within
// rounding of a shadow edge differs (by 1/N of its light per flipped sample); on llvmpipe 4 of
// the box's 1500 surfels do (rel RMS 6e-3), its caches and grid agree to 4e-8.
constexpr double kRelRms = 1e-2, kDiffer = 0.01;

TEST(GpuEmitters, CornellBoxSurfelsCachesAndGridMatchTheHost) {
  REQUIRE_GPU();
  const Cornell& f = cornell();
  // One layer per emissive material, as EmissionState samples them.
  const auto layout = relight::detail::EmitterLayout::of(f.scene, {}, 1024);
  const EmitterSampler sampler(f.scene, *f.accel, layout.sampled, layout.layer_of_material);
  ASSERT_GT(sampler.triangleCount(), 0u);
  Gpu gpu(f.scene, *f.accel);
  ASSERT_TRUE(gpu.sampling);

  // Surfels, 16 samples each.
  const auto& surfels = f.p.surfels;
  std::size_t host_rays = 0, gpu_rays = 0;
  const auto host_s = hostIrradiance(sampler, surfels.position, surfels.normal, 16, host_rays);
  const auto rot_s = rotations(surfels.size(), [](std::size_t s) { return relight::detail::surfelEmitterSeed(s); });
  std::vector<float> gpu_s;
  auto ran = gpu.sampling->trace(sampler, EmitterReceivers{surfels.position, surfels.normal, {}, rot_s}, 16, 0,
                                 "surfel_emitter", gpu_s, gpu_rays);
  ASSERT_TRUE(ran) << ran.status().toString();
  ASSERT_TRUE(*ran) << gpu.sampling->declined();
  const Compare cs = compare(gpu_s, host_s, 3 * std::size_t(sampler.layerCount()));
  std::printf("surfels: %zu, rel RMS %.2e, points differing %.2f %%, dark %.1f %%, rays host %zu gpu %zu\n",
              surfels.size(), cs.rel_rms, 100 * cs.differ, 100 * cs.zero, host_rays, gpu_rays);
  EXPECT_LT(cs.rel_rms, kRelRms);
  EXPECT_LT(cs.differ, kDiffer);
  EXPECT_GT(cs.zero, 0.0);  // the blocks shadow some surfels: occlusion is exercised
  EXPECT_EQ(gpu_rays, host_rays);

  // Lightmap caches, 64 samples each.
  const auto& lm = f.p.lightmap;
  host_rays = 0, gpu_rays = 0;
  std::vector<float> host_c, gpu_c;
  relight::detail::sampleEmitters(sampler, lm, 64, 0, host_c, host_rays);
  const auto rot_c = rotations(lm.size(), [&](std::size_t c) { return relight::detail::texelEmitterSeed(lm.texel[c], 0); });
  ran = gpu.sampling->trace(sampler, EmitterReceivers{lm.position, lm.normal, lm.valid, rot_c}, 64, 0,
                            "emissive_direct", gpu_c, gpu_rays);
  ASSERT_TRUE(ran && *ran);
  const Compare cc = compare(gpu_c, host_c, 3 * std::size_t(sampler.layerCount()));
  std::printf("lightmap caches: %zu, rel RMS %.2e, points differing %.2f %%, rays host %zu gpu %zu\n", lm.size(),
              cc.rel_rms, 100 * cc.differ, host_rays, gpu_rays);
  EXPECT_LT(cc.rel_rms, kRelRms);
  EXPECT_LT(cc.differ, kDiffer);
  EXPECT_EQ(gpu_rays, host_rays);

  // Grid caches, SH of 3 bands, 64 samples each.
  const auto& grid = f.p.grid;
  ASSERT_GT(grid.size(), 0u);
  host_rays = 0, gpu_rays = 0;
  std::vector<float> host_g, gpu_g;
  relight::detail::sampleEmittersSh(sampler, grid, 3, 64, host_g, host_rays);
  const auto rot_g = rotations(grid.size(), [](std::size_t c) { return relight::detail::gridEmitterSeed(c); });
  ran = gpu.sampling->trace(sampler, EmitterReceivers{grid.position, {}, grid.valid, rot_g}, 64, 3, "grid_emitter",
                            gpu_g, gpu_rays);
  ASSERT_TRUE(ran && *ran);
  const Compare cg = compare(gpu_g, host_g, 27 * std::size_t(sampler.layerCount()));
  std::printf("grid caches: %zu, rel RMS %.2e, points differing %.2f %%, rays host %zu gpu %zu\n", grid.size(),
              cg.rel_rms, 100 * cg.differ, host_rays, gpu_rays);
  EXPECT_LT(cg.rel_rms, kRelRms);
  EXPECT_LT(cg.differ, kDiffer);
  EXPECT_EQ(gpu_rays, host_rays);

  // Any number of lanes per point: the same sums in the same order, the same bits.
  {
    GpuEmitterSampling one_lane(f.scene, *f.accel, 1);
    std::vector<float> c1, g1;
    std::size_t r1 = 0;
    ran = one_lane.trace(sampler, EmitterReceivers{lm.position, lm.normal, lm.valid, rot_c}, 64, 0, "emissive_direct",
                         c1, r1);
    ASSERT_TRUE(ran && *ran);
    ran = one_lane.trace(sampler, EmitterReceivers{grid.position, {}, grid.valid, rot_g}, 64, 3, "grid_emitter", g1, r1);
    ASSERT_TRUE(ran && *ran);
    ASSERT_EQ(c1.size(), gpu_c.size());
    ASSERT_EQ(g1.size(), gpu_g.size());
    EXPECT_EQ(std::memcmp(c1.data(), gpu_c.data(), c1.size() * sizeof(float)), 0);
    EXPECT_EQ(std::memcmp(g1.data(), gpu_g.data(), g1.size() * sizeof(float)), 0);
  }

  // Determinism: a second run gives the same bits.
  std::vector<float> again;
  std::size_t r2 = 0;
  ran = gpu.sampling->trace(sampler, EmitterReceivers{lm.position, lm.normal, lm.valid, rot_c}, 64, 0,
                            "emissive_direct", again, r2);
  ASSERT_TRUE(ran && *ran);
  ASSERT_EQ(again.size(), gpu_c.size());
  EXPECT_EQ(std::memcmp(again.data(), gpu_c.data(), again.size() * sizeof(float)), 0);
}

// A quad corner, corner + e0, corner + e0 + e1, corner + e1, front along cross(e0, e1).
scene::MeshInstance quad(const std::string& name, glm::vec3 corner, glm::vec3 e0, glm::vec3 e1, int material) {
  scene::MeshInstance m;
  m.name = name;
  m.positions = {corner, corner + e0, corner + e0 + e1, corner + e1};
  m.normals.assign(4, glm::normalize(glm::cross(e0, e1)));
  m.indices = {0, 1, 2, 0, 2, 3};
  m.material = material;
  return m;
}

// A 2 m floor, a 0.5 m lamp 1 m above it facing down (as lamp_cells^2 quads of two emissive
// materials in a checker), a plate halfway between that covers half of the lamp's footprint:
// umbra, penumbra and lit floor.
scene::Scene plateOverFloor(bool cutout_plate, int lamp_cells = 1) {
  scene::Scene s;
  scene::Material grey, lamp, plate;
  lamp.emissive_factor = glm::vec3(1.0f, 0.8f, 0.6f);
  lamp.emissive_strength = 5.0f;
  if (cutout_plate) plate.alpha_mode = scene::Material::AlphaMode::kMask;
  scene::Material lamp2 = lamp;  // a second emissive material: a second layer
  lamp2.emissive_factor = glm::vec3(0.3f, 0.6f, 1.0f);
  s.materials = {grey, lamp, plate, lamp2};
  s.meshes.push_back(quad("floor", glm::vec3(-1, 0, -1), glm::vec3(0, 0, 2), glm::vec3(2, 0, 0), 0));
  const float cell = 0.5f / float(lamp_cells);
  for (int i = 0; i < lamp_cells; ++i)
    for (int j = 0; j < lamp_cells; ++j)
      s.meshes.push_back(quad("lamp", glm::vec3(-0.25f + cell * float(i), 1, -0.25f + cell * float(j)),
                              glm::vec3(cell, 0, 0), glm::vec3(0, 0, cell), (i + j) % 2 ? 3 : 1));
  s.meshes.push_back(quad("plate", glm::vec3(0.0f, 0.5f, -0.4f), glm::vec3(0.8f, 0, 0), glm::vec3(0, 0, 0.8f), 2));
  s.scale = 2.9f;
  return s;
}

// lamp_cells 1: 2 emitting triangles, each point picks by its own weights; 6: 72 triangles of
// two materials (two layers), more than EmitterSampler::kLocalPickMax, so every point picks by
// power alone.
void plateShadow(int lamp_cells) {
  const scene::Scene s = plateOverFloor(false, lamp_cells);
  auto accel = rt::Accel::build(s);
  ASSERT_TRUE(accel) << accel.status().toString();
  const auto layout = relight::detail::EmitterLayout::of(s, {}, 1024);
  const EmitterSampler sampler(s, *accel, layout.sampled, layout.layer_of_material);
  ASSERT_EQ(sampler.layerCount(), lamp_cells > 1 ? 2 : 1);
  ASSERT_EQ(sampler.triangleCount(), std::size_t(2 * lamp_cells * lamp_cells));
  ASSERT_EQ(sampler.triangleCount() > EmitterSampler::kLocalPickMax, lamp_cells > 5);
  std::vector<glm::vec3> pos, nrm;
  for (int i = 0; i < 48; ++i)
    for (int j = 0; j < 48; ++j) pos.push_back(glm::vec3(-0.98f + 0.04f * i, 0.0f, -0.98f + 0.04f * j));
  nrm.assign(pos.size(), glm::vec3(0, 1, 0));
  std::size_t host_rays = 0, gpu_rays = 0;
  const auto host = hostIrradiance(sampler, pos, nrm, 64, host_rays);
  Gpu gpu(s, *accel);
  ASSERT_TRUE(gpu.sampling);
  const auto rot = rotations(pos.size(), [](std::size_t p) { return relight::detail::surfelEmitterSeed(p); });
  std::vector<float> out;
  auto ran = gpu.sampling->trace(sampler, EmitterReceivers{pos, nrm, {}, rot}, 64, 0, "surfel_emitter", out, gpu_rays);
  ASSERT_TRUE(ran) << ran.status().toString();
  ASSERT_TRUE(*ran) << gpu.sampling->declined();
  // How much the plate matters: the floor's light with nothing in the way is larger.
  double lit = 0.0, open = 0.0;
  {
    scene::Scene bare = s;
    bare.meshes.pop_back();
    auto bare_accel = rt::Accel::build(bare);
    ASSERT_TRUE(bare_accel);
    const EmitterSampler bare_sampler(bare, *bare_accel, {});
    std::size_t r = 0;
    const auto unshadowed = hostIrradiance(bare_sampler, pos, nrm, 64, r);
    for (float v : host) lit += v;
    for (float v : unshadowed) open += v;
  }
  const Compare c = compare(out, host, 3 * std::size_t(sampler.layerCount()));
  std::printf("plate over floor, %zu lamp triangles: rel RMS %.2e, points differing %.2f %%, umbra %.1f %%, plate keeps %.1f %% of the light\n",
              sampler.triangleCount(), c.rel_rms, 100 * c.differ, 100 * c.zero, 100 * (1.0 - lit / open));
  EXPECT_GT(1.0 - lit / open, 0.1);  // occlusion matters here
  EXPECT_LT(c.rel_rms, kRelRms);
  EXPECT_LT(c.differ, kDiffer);
  EXPECT_EQ(gpu_rays, host_rays);
}

TEST(GpuEmitters, PlateShadowOnTheFloorMatchesTheHost) {
  REQUIRE_GPU();
  plateShadow(1);
}

TEST(GpuEmitters, PlateShadowFromAManyTriangleLampMatchesTheHost) {
  REQUIRE_GPU();
  plateShadow(6);
}

TEST(GpuEmitters, CutoutsGoBackToTheHost) {
  REQUIRE_GPU();
  const scene::Scene s = plateOverFloor(true);
  auto accel = rt::Accel::build(s);
  ASSERT_TRUE(accel);
  const EmitterSampler sampler(s, *accel, {});
  Gpu gpu(s, *accel);
  ASSERT_TRUE(gpu.sampling);
  const std::vector<glm::vec3> pos{glm::vec3(0.0f)}, nrm{glm::vec3(0, 1, 0)};
  const std::vector<glm::vec2> rot{glm::vec2(0.5f)};
  std::vector<float> out;
  std::size_t rays = 0;
  auto ran = gpu.sampling->trace(sampler, EmitterReceivers{pos, nrm, {}, rot}, 8, 0, "surfel_emitter", out, rays);
  ASSERT_TRUE(ran) << ran.status().toString();
  EXPECT_FALSE(*ran);
  EXPECT_NE(gpu.sampling->declined().find("cut-out"), std::string::npos) << gpu.sampling->declined();
}

// Through the GPU backend: the emitter stages run on the GPU (their GPU timer stages are in
// the relight's timings) and the lightmap's emitter direct light matches the CPU backend's.
TEST(GpuEmitters, GpuBackendSamplesTheEmittersOnTheGpu) {
  REQUIRE_GPU();
  const Cornell& f = cornell();
  auto cpu = relight::makeCpuBackend(f.scene, *f.accel, f.p, f.p.lightmap_links.view(), f.p.grid_links.view());
  ASSERT_TRUE(cpu);
  auto gpu = makeGpuBackend(f.scene, *f.accel, f.p, f.p.lightmap_links.view(), f.p.grid_links.view());
  ASSERT_TRUE(gpu) << gpu.status().toString();
  relight::LightSet lights = relight::LightSet::fromSceneLights(f.scene.lights);
  const relight::LightSet scene_lights = relight::LightSet::fromSceneLights(f.scene.lights);
  for (const auto& l : scene_lights.lights()) {
    relight::LightEntry realtime = l;  // direct = the emitters' only (no shadow maps in it)
    realtime.baked = false;
    ASSERT_TRUE(lights.modify(realtime));
  }
  relight::RelightOptions o;
  o.max_bounces = 1;
  o.emitter_samples = 32;
  relight::RelightResult rc, rg;
  ASSERT_TRUE((*cpu)->relightInto(lights, o, rc));
  ASSERT_TRUE((*gpu)->relightInto(lights, o, rg));
  auto stage = [&](const std::string& name) {
    for (const auto& t : rg.timings)
      if (t.stage == name) return true;
    return false;
  };
  EXPECT_TRUE(stage("surfel_emitter_gpu"));
  EXPECT_TRUE(stage("emissive_direct_gpu"));
  EXPECT_TRUE(stage("grid_emitter_gpu"));
  std::vector<float> dg(reinterpret_cast<const float*>(rg.direct.data()),
                        reinterpret_cast<const float*>(rg.direct.data()) + 3 * rg.direct.size());
  std::vector<float> dc(reinterpret_cast<const float*>(rc.direct.data()),
                        reinterpret_cast<const float*>(rc.direct.data()) + 3 * rc.direct.size());
  const Compare c = compare(dg, dc, 3);
  std::printf("GPU backend vs CPU backend, emitter direct per texel: rel RMS %.2e, texels differing %.2f %%\n",
              c.rel_rms, 100 * c.differ);
  EXPECT_LT(c.rel_rms, kRelRms);
  EXPECT_LT(c.differ, kDiffer);
  for (const auto& note : rg.plan.reasons) EXPECT_EQ(note.find("sampled on the host"), std::string::npos) << note;
  // Everything downstream (bounces, grid, texels) as with the host's samples on the same backend.
  GpuOptions host_emitters;
  host_emitters.emitter_sampling = false;
  auto gpu_host = makeGpuBackend(f.scene, *f.accel, f.p, f.p.lightmap_links.view(), f.p.grid_links.view(), host_emitters);
  ASSERT_TRUE(gpu_host) << gpu_host.status().toString();
  relight::RelightResult rh;
  ASSERT_TRUE((*gpu_host)->relightInto(lights, o, rh));
  for (const auto& t : rh.timings) EXPECT_EQ(t.stage.find("_gpu"), std::string::npos) << t.stage;
  const Compare lm = compare(rg.lightmap_sh, rh.lightmap_sh, std::size_t(3) * rg.bands * rg.bands);
  const Compare grid = compare(rg.grid_sh, rh.grid_sh, std::size_t(3) * rg.bands * rg.bands);
  std::printf("GPU backend, emitters sampled on the GPU vs on the host: lightmap SH rel RMS %.2e, grid SH %.2e\n",
              lm.rel_rms, grid.rel_rms);
  EXPECT_LT(lm.rel_rms, kRelRms);
  EXPECT_LT(grid.rel_rms, kRelRms);
}

// The finer direct layer's emitter samples run on the GPU too, and match the CPU backend's.
TEST(GpuEmitters, DirectLayerSamplesTheEmittersOnTheGpu) {
  REQUIRE_GPU();
  std::unique_ptr<Cornell> f(makeCornell(2));
  ASSERT_TRUE(f->p.hasDirectLayer());
  auto cpu = relight::makeCpuBackend(f->scene, *f->accel, f->p, f->p.lightmap_links.view(), f->p.grid_links.view());
  ASSERT_TRUE(cpu);
  auto gpu = makeGpuBackend(f->scene, *f->accel, f->p, f->p.lightmap_links.view(), f->p.grid_links.view());
  ASSERT_TRUE(gpu) << gpu.status().toString();
  relight::LightSet lights;  // the emitters alone
  relight::RelightOptions o;
  o.max_bounces = 0;
  o.emitter_samples = 16;
  relight::RelightResult rc, rg;
  ASSERT_TRUE((*cpu)->relightInto(lights, o, rc));
  ASSERT_TRUE((*gpu)->relightInto(lights, o, rg));
  ASSERT_TRUE(rg.directIsFiner());
  bool staged = false;
  for (const auto& t : rg.timings) staged = staged || t.stage == "direct_layer_emitter_gpu";
  EXPECT_TRUE(staged);
  EXPECT_EQ(rg.counts.shadow_rays, rc.counts.shadow_rays);
  const auto* g = reinterpret_cast<const float*>(rg.direct.data());
  const auto* c = reinterpret_cast<const float*>(rc.direct.data());
  const Compare cmp = compare(std::vector<float>(g, g + 3 * rg.direct.size()), std::vector<float>(c, c + 3 * rc.direct.size()), 3);
  std::printf("direct layer %dx%d, GPU vs CPU backend: rel RMS %.2e, texels differing %.2f %%\n", rg.direct_width,
              rg.direct_height, cmp.rel_rms, 100 * cmp.differ);
  EXPECT_LT(cmp.zero, 0.5);  // the emitters light most of the layer
  EXPECT_LT(cmp.rel_rms, kRelRms);
  EXPECT_LT(cmp.differ, kDiffer);
}

TEST(GpuEmitters, TexturedEmissionGoesBackToTheHost) {
  REQUIRE_GPU();
  scene::Scene s = plateOverFloor(false);
  scene::Texture t;
  t.name = "glow";
  t.width = t.height = 1;
  t.rgba8 = {255, 128, 64, 255};
  s.textures.push_back(t);
  s.materials[1].emissive_texture.texture = 0;
  for (auto& mesh : s.meshes)
    if (mesh.material == 1) mesh.uv0.assign(mesh.positions.size(), glm::vec2(0.5f));
  auto accel = rt::Accel::build(s);
  ASSERT_TRUE(accel);
  const EmitterSampler sampler(s, *accel, {});
  EXPECT_FALSE(sampler.uniformRadiance());
  Gpu gpu(s, *accel);
  ASSERT_TRUE(gpu.sampling);
  const std::vector<glm::vec3> pos{glm::vec3(0.0f)}, nrm{glm::vec3(0, 1, 0)};
  const std::vector<glm::vec2> rot{glm::vec2(0.5f)};
  std::vector<float> out;
  std::size_t rays = 0;
  auto ran = gpu.sampling->trace(sampler, EmitterReceivers{pos, nrm, {}, rot}, 8, 0, "surfel_emitter", out, rays);
  ASSERT_TRUE(ran) << ran.status().toString();
  EXPECT_FALSE(*ran);
  EXPECT_NE(gpu.sampling->declined().find("texture"), std::string::npos) << gpu.sampling->declined();
  // A kRadiance override replaces the texture by a constant: the GPU runs it.
  const relight::EmissiveOverride constant{1, relight::EmissiveOverride::Mode::kRadiance, glm::vec3(2.0f)};
  const EmitterSampler replaced(s, *accel, std::vector<relight::EmissiveOverride>{constant});
  EXPECT_TRUE(replaced.uniformRadiance());
  ran = gpu.sampling->trace(replaced, EmitterReceivers{pos, nrm, {}, rot}, 8, 0, "surfel_emitter", out, rays);
  ASSERT_TRUE(ran && *ran) << gpu.sampling->declined();
}

// A scene with an alpha cut-out among the shadow casters: the relight samples the emitters on
// the host and its plan says so (the block's material is a mask at alpha 1: still opaque).
TEST(GpuEmitters, CutoutSceneIsSampledOnTheHostAndTheRelightSaysSo) {
  REQUIRE_GPU();
  const Cornell& f = cornell();
  scene::Scene s = f.scene;
  scene::Material mask;
  mask.alpha_mode = scene::Material::AlphaMode::kMask;
  s.materials.push_back(mask);
  for (auto& mesh : s.meshes)
    if (mesh.is_static && !s.materialOf(mesh).isEmissive()) {
      mesh.material = int(s.materials.size()) - 1;
      break;
    }
  auto accel = rt::Accel::build(s);
  ASSERT_TRUE(accel);
  auto gpu = makeGpuBackend(s, *accel, f.p, f.p.lightmap_links.view(), f.p.grid_links.view());
  ASSERT_TRUE(gpu) << gpu.status().toString();
  relight::LightSet lights;
  relight::RelightOptions o;
  o.max_bounces = 0;
  o.emitter_samples = 4;
  relight::RelightResult r;
  ASSERT_TRUE((*gpu)->relightInto(lights, o, r));
  int notes = 0;
  for (const auto& reason : r.plan.reasons)
    if (reason.find("sampled on the host") != std::string::npos && reason.find("cut-out") != std::string::npos) ++notes;
  EXPECT_GE(notes, 2) << "surfels and lightmap caches";
  for (const auto& t : r.timings) EXPECT_EQ(t.stage.find("_gpu"), std::string::npos) << t.stage;
}

}  // namespace
}  // namespace lightlink::gpu
