// The reference path tracer against cases with a closed-form answer (DESIGN.md sec 7):
// closed uniform emitters (E = pi L at every point and normal), the furnace (B = E0 / (1 -
// rho)), punctual lights over a plane (exact), polygon emitters (Lambert's formula), skies,
// and its own contracts (split, bounce cap, determinism, overrides, validation, budget).
// Statistical checks allow 3 standard errors of the reference's own estimate; seeds are
// fixed, so each check passes or fails the same way every run.
#include "core/reference/reference.h"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstring>
#include <limits>
#include <memory>
#include <numbers>
#include <optional>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include "core/common/sampling.h"
#include "core/sh/sh.h"
#include "tests/common/scene_builders.h"

namespace lightlink::reference {
namespace {

using scene::MeshInstance;
using scene::Scene;
constexpr float kPi = std::numbers::pi_v<float>;

using lightlink::testing::addBox;
using lightlink::testing::addMaterial;
using lightlink::testing::addQuad;

// Latitude-longitude sphere facing inwards, flat-shaded: closed, triangles of unequal area.
void addInwardSphere(Scene& s, glm::vec3 centre, float radius, int material) {
  constexpr int kRings = 12, kSegments = 24;
  MeshInstance m;
  m.name = "sphere";
  m.material = material;
  const auto at = [&](int ring, int seg) {
    const float theta = kPi * float(ring) / kRings, phi = 2.0f * kPi * float(seg) / kSegments;
    return centre + radius * glm::vec3(std::sin(theta) * std::cos(phi), std::sin(theta) * std::sin(phi), std::cos(theta));
  };
  for (int r = 0; r < kRings; ++r)
    for (int g = 0; g < kSegments; ++g) {
      const glm::vec3 a = at(r, g), b = at(r + 1, g), c = at(r + 1, g + 1), d = at(r, g + 1);
      // Inward winding: (a, c, b) and (a, d, c) have normals towards the centre.
      const auto tri = [&](glm::vec3 p, glm::vec3 q, glm::vec3 w) {
        if (glm::length(glm::cross(q - p, w - p)) < 1e-9f) return;  // pole slivers
        const auto base = std::uint32_t(m.positions.size());
        m.positions.insert(m.positions.end(), {p, q, w});
        m.indices.insert(m.indices.end(), {base, base + 1, base + 2});
      };
      tri(a, c, b);
      tri(a, d, c);
    }
  for (std::size_t i = 0; i < m.positions.size(); i += 3) {
    const glm::vec3 n = glm::normalize(glm::cross(m.positions[i + 1] - m.positions[i], m.positions[i + 2] - m.positions[i]));
    m.normals.insert(m.normals.end(), {n, n, n});
  }
  s.meshes.push_back(m);
}

// A scene, its accel and a renderer over a light set, built in that order.
struct World {
  Scene scene;
  std::optional<rt::Accel> accel;
  std::optional<ReferenceRenderer> renderer;

  static std::unique_ptr<World> make(Scene s, const relight::LightSet& lights = {}) {
    auto w = std::make_unique<World>();
    s.source_path = "test-scene";
    lightlink::testing::finishScene(s);
    w->scene = std::move(s);
    auto a = rt::Accel::build(w->scene);
    EXPECT_TRUE(a) << a.status().toString();
    if (!a) return nullptr;
    w->accel.emplace(std::move(a).value());
    auto r = ReferenceRenderer::create(w->scene, *w->accel, lights);
    EXPECT_TRUE(r) << r.status().toString();
    if (!r) return nullptr;
    w->renderer.emplace(std::move(r).value());
    return w;
  }

  std::vector<IrradianceEstimate> run(const std::vector<glm::vec3>& p, const std::vector<glm::vec3>& n,
                                      const ReferenceOptions& o = {}) const {
    auto r = renderer->irradiance({p, n}, o);
    EXPECT_TRUE(r) << r.status().toString();
    return r ? std::move(r).value() : std::vector<IrradianceEstimate>{};
  }
};

// Deterministic pseudo-random numbers for test inputs.
struct TestRng {
  std::uint64_t state;
  float next() { return unitFloat(mixBits(++state * 0x9e3779b97f4a7c15ULL)); }
  glm::vec3 direction() { return uniformSphere(next(), next()); }
};

// |estimate - expected| <= 3 sigma per channel, with a float-rounding floor.
void expectWithin3Sigma(glm::vec3 estimate, glm::vec3 sigma, glm::vec3 expected, const std::string& what) {
  for (int c = 0; c < 3; ++c)
    EXPECT_LE(std::abs(estimate[c] - expected[c]), 3.0f * sigma[c] + 1e-5f * std::abs(expected[c]))
        << what << " channel " << c << ": " << estimate[c] << " vs " << expected[c] << " (sigma " << sigma[c] << ")";
}

TEST(Reference, ClosedEmissiveBoxGivesPiLEverywhere) {
  Scene s;
  const glm::vec3 le(1.0f, 2.0f, 0.5f);
  addBox(s, glm::vec3(0.0f), glm::vec3(2.0f, 1.0f, 3.0f), true, addMaterial(s, glm::vec3(0.0f), le));
  auto w = World::make(std::move(s));
  ASSERT_TRUE(w);
  EXPECT_EQ(w->renderer->emitterTriangleCount(), 12u);
  TestRng rng{1};
  std::vector<glm::vec3> p, n;
  for (int i = 0; i < 8; ++i) {
    p.push_back(glm::vec3(0.05f) + glm::vec3(1.9f * rng.next(), 0.9f * rng.next(), 2.9f * rng.next()));
    n.push_back(rng.direction());
  }
  p.push_back({1.0f, 0.5f, 0.0f});  // on the floor, like a lightmap texel
  n.push_back({0.0f, 0.0f, 1.0f});
  const auto est = w->run(p, n);
  ASSERT_EQ(est.size(), p.size());
  for (std::size_t i = 0; i < est.size(); ++i) {
    const auto& e = est[i];
    expectWithin3Sigma(e.total, e.std_error_total, kPi * le, "point " + std::to_string(i));
    EXPECT_TRUE(e.converged);
    EXPECT_LE(e.std_error_total.y, 0.0101f * e.total.y);
    EXPECT_GT(e.std_error_total.y, 0.0f);
    EXPECT_EQ(e.indirect, glm::vec3(0.0f));  // albedo 0: nothing bounces
    EXPECT_EQ(e.direct_punctual, glm::vec3(0.0f));
  }
}

TEST(Reference, ClosedEmissiveSphereGivesPiLEverywhere) {
  Scene s;
  const glm::vec3 le(0.25f);
  addInwardSphere(s, glm::vec3(1.0f, -2.0f, 0.5f), 1.5f, addMaterial(s, glm::vec3(0.0f), le));
  auto w = World::make(std::move(s));
  ASSERT_TRUE(w);
  TestRng rng{2};
  std::vector<glm::vec3> p, n;
  for (int i = 0; i < 6; ++i) {
    p.push_back(glm::vec3(1.0f, -2.0f, 0.5f) + 1.1f * rng.next() * rng.direction());
    n.push_back(rng.direction());
  }
  for (const auto& e : w->run(p, n)) expectWithin3Sigma(e.total, e.std_error_total, kPi * le, "sphere");
}

// Furnace: every wall emits L_e and reflects rho, so the radiance everywhere inside is
// L = L_e / (1 - rho), E = pi L_e / (1 - rho), of which pi L_e is direct.
TEST(Reference, FurnaceBoxMatchesGeometricSeries) {
  // Grey 0.5 and 0.8, and a coloured albedo: roulette survives by the largest channel, so
  // the others must come out right through the 1 / survival weight.
  for (const glm::vec3 rho : {glm::vec3(0.5f), glm::vec3(0.8f), glm::vec3(0.3f, 0.6f, 0.8f)}) {
    Scene s;
    const glm::vec3 le(0.3f, 0.6f, 1.0f);
    addBox(s, glm::vec3(-1.0f), glm::vec3(1.0f, 2.0f, 1.5f), true, addMaterial(s, rho, le));
    auto w = World::make(std::move(s));
    ASSERT_TRUE(w);
    TestRng rng{3};
    std::vector<glm::vec3> p, n;
    for (int i = 0; i < 4; ++i) {
      p.push_back(glm::vec3(-0.9f) + glm::vec3(1.8f * rng.next(), 2.8f * rng.next(), 2.3f * rng.next()));
      n.push_back(rng.direction());
    }
    const glm::vec3 expected = kPi * le / (1.0f - rho);
    ReferenceOptions o;
    o.target_rel_error = 0.005f;
    for (const auto& e : w->run(p, n, o)) {
      const std::string what = "rho " + std::to_string(rho.x) + "," + std::to_string(rho.z);
      expectWithin3Sigma(e.total, e.std_error_total, expected, what + " total");
      expectWithin3Sigma(e.direct, e.std_error_direct, kPi * le, what + " direct");
      expectWithin3Sigma(e.indirect, e.std_error_indirect, expected - kPi * le, what + " indirect");
      EXPECT_EQ(e.truncated_paths, 0u);
      EXPECT_TRUE(e.converged);
    }
  }
}

// Albedo and emission come from the textures (sRGB decoded), not only the factors: a furnace
// whose walls carry constant textures gives pi L_e / (1 - rho) with the textures' linear values.
// The emitter pmf is built from the factor alone (an upper bound), so this also checks that
// sampling by the bound stays unbiased where the texture is darker.
TEST(Reference, TexturedFurnaceUsesTextureValues) {
  Scene s;
  const auto constant = [&](std::uint8_t r, std::uint8_t g, std::uint8_t b) {
    scene::Texture t;
    t.name = "t" + std::to_string(s.textures.size());
    t.width = t.height = 2;
    for (int i = 0; i < 4; ++i) t.rgba8.insert(t.rgba8.end(), {r, g, b, 255});
    s.textures.push_back(t);
    return int(s.textures.size()) - 1;
  };
  const int m = addMaterial(s, glm::vec3(1.0f), glm::vec3(2.0f));
  s.materials[std::size_t(m)].base_color_texture.texture = constant(200, 150, 100);
  s.materials[std::size_t(m)].emissive_texture.texture = constant(128, 128, 255);
  addBox(s, glm::vec3(0.0f), glm::vec3(1.0f, 2.0f, 1.0f), true, m);
  for (auto& mesh : s.meshes) mesh.uv0 = {{0, 0}, {1, 0}, {1, 1}, {0, 1}};
  const glm::vec3 rho(s.textures[0].sampleSrgb({0.5f, 0.5f}));
  const glm::vec3 le = 2.0f * glm::vec3(s.textures[1].sampleSrgb({0.5f, 0.5f}));
  ASSERT_LT(rho.z, 0.2f);  // the texture, not the factor 1, decides
  ASSERT_LT(le.x, 0.5f);
  auto w = World::make(std::move(s));
  ASSERT_TRUE(w);
  ReferenceOptions o;
  o.target_rel_error = 0.005f;
  const auto e = w->run({glm::vec3(0.3f, 1.2f, 0.6f)}, {glm::normalize(glm::vec3(1, -1, 0.5f))}, o).at(0);
  expectWithin3Sigma(e.total, e.std_error_total, kPi * le / (1.0f - rho), "textured furnace");
}

// The bounce cap counts bounces: max_bounces = k gives pi L_e (1 + rho + ... + rho^k).
TEST(Reference, BounceCapTruncatesTheSeriesExactly) {
  const float rho = 0.5f;
  Scene s;
  const glm::vec3 le(1.0f);
  addBox(s, glm::vec3(0.0f), glm::vec3(1.0f), true, addMaterial(s, glm::vec3(rho), le));
  auto w = World::make(std::move(s));
  ASSERT_TRUE(w);
  float series = 0.0f;
  for (int k = 0; k <= 2; ++k) {
    series += std::pow(rho, float(k));
    ReferenceOptions o;
    o.max_bounces = k;
    const auto e = w->run({glm::vec3(0.4f, 0.5f, 0.6f)}, {glm::vec3(0.0f, 1.0f, 0.0f)}, o).at(0);
    expectWithin3Sigma(e.total, e.std_error_total, kPi * le * series, "max_bounces " + std::to_string(k));
    if (k == 0) {
      EXPECT_EQ(e.indirect, glm::vec3(0.0f));
    }
    EXPECT_GT(e.truncated_paths, 0u);  // with rho > 0 every surviving path reaches the cap
  }
}

// A point light of I cd at height h over a plane: E = I cos(theta) / d^2, exactly (next-event
// estimation at the query point is deterministic). Light reflected by the plane never comes
// back to it, so there is no indirect light and no variance.
TEST(Reference, PointLightOverPlaneIsExact) {
  Scene s;
  addQuad(s, {-50, -50, 0}, {50, -50, 0}, {50, 50, 0}, {-50, 50, 0}, addMaterial(s, glm::vec3(0.5f)));
  relight::LightSet lights;
  scene::Light point;
  point.kind = scene::Light::Kind::kPoint;
  point.intensity = 10.0f;
  point.color = {1.0f, 0.5f, 0.25f};
  point.position = {0.0f, 0.0f, 2.0f};
  ASSERT_TRUE(lights.add({"bulb", point, true}));
  scene::Light sun;
  sun.kind = scene::Light::Kind::kDirectional;
  sun.intensity = 3.0f;
  sun.direction = glm::normalize(glm::vec3(-1.0f, 0.0f, -1.0f));
  ASSERT_TRUE(lights.add({"sun", sun, false}));
  auto w = World::make(std::move(s), lights);
  ASSERT_TRUE(w);
  const glm::vec3 up(0, 0, 1);
  const float sun_e = 3.0f * std::sqrt(0.5f);
  const auto est = w->run({{0, 0, 0}, {1.5f, 0, 0}, {0, 0, -0.5f}}, {up, up, up});
  ASSERT_EQ(est.size(), 3u);
  const glm::vec3 below = point.color * (10.0f / 4.0f) + glm::vec3(sun_e);
  const glm::vec3 off_axis = point.color * (10.0f * 0.8f / 6.25f) + glm::vec3(sun_e);
  for (int c = 0; c < 3; ++c) {
    EXPECT_NEAR(est[0].total[c], below[c], 1e-5f * below[c]);
    EXPECT_NEAR(est[1].total[c], off_axis[c], 1e-5f * off_axis[c]);
  }
  EXPECT_EQ(est[2].total, glm::vec3(0.0f));  // under the plane: both lights shadowed
  for (const auto& e : est) {
    EXPECT_EQ(e.direct_punctual, e.total);
    EXPECT_EQ(e.indirect, glm::vec3(0.0f));
    EXPECT_EQ(e.std_error_total, glm::vec3(0.0f));
    EXPECT_TRUE(e.converged);
    EXPECT_EQ(e.samples, 64u);  // min_samples: zero variance converges at once
  }
}

// Lambert's formula for the irradiance from a uniform polygon emitter of radiance L:
// E = L / 2 * |sum_i angle(v_i, v_i+1) * dot(n, normalize(cross(v_i, v_i+1)))|, v_i unit vectors
// from the point to the corners, valid when the polygon lies wholly above the tangent plane.
float polygonIrradiance(glm::vec3 p, glm::vec3 n, const std::vector<glm::vec3>& corners, float radiance) {
  for (const glm::vec3& c : corners) EXPECT_GT(glm::dot(n, c - p), 0.0f) << "the formula needs the polygon above the plane";
  float sum = 0.0f;
  for (std::size_t i = 0; i < corners.size(); ++i) {
    const glm::vec3 a = glm::normalize(corners[i] - p), b = glm::normalize(corners[(i + 1) % corners.size()] - p);
    sum += std::acos(std::clamp(glm::dot(a, b), -1.0f, 1.0f)) * glm::dot(n, glm::normalize(glm::cross(a, b)));
  }
  return 0.5f * radiance * std::abs(sum);
}

// A small and a large quad emitter over points below it: next-event estimation and cosine
// sampling combined by MIS must reproduce the form factor for both. The single-sided quad is
// black from above; the double-sided one emits on both sides.
TEST(Reference, QuadEmitterMatchesPolygonFormula) {
  for (const bool double_sided : {false, true}) {
    for (const float half : {0.1f, 2.0f}) {
      Scene s;
      const float l = 5.0f;
      const std::vector<glm::vec3> quad = {{-half, -half, 1}, {-half, half, 1}, {half, half, 1}, {half, -half, 1}};
      addQuad(s, quad[0], quad[1], quad[2], quad[3], addMaterial(s, glm::vec3(0.0f), glm::vec3(l), double_sided));
      ASSERT_LT(glm::cross(quad[1] - quad[0], quad[2] - quad[0]).z, 0.0f);  // faces down
      auto w = World::make(std::move(s));
      ASSERT_TRUE(w);
      const std::vector<glm::vec3> p = {{0, 0, 0}, {0.3f, -0.2f, 0.4f}, {0.05f, 0.05f, 2.0f}};
      const std::vector<glm::vec3> n = {{0, 0, 1}, glm::normalize(glm::vec3(0.05f, 0.02f, 1.0f)), {0, 0, -1}};
      ReferenceOptions o;
      o.target_rel_error = 0.005f;  // a 1 % bias in either strategy shows
      const auto est = w->run(p, n, o);
      ASSERT_EQ(est.size(), 3u);
      for (int i = 0; i < 2; ++i) {
        const float expected = polygonIrradiance(p[std::size_t(i)], n[std::size_t(i)], quad, l);
        expectWithin3Sigma(est[std::size_t(i)].total, est[std::size_t(i)].std_error_total, glm::vec3(expected),
                           "half " + std::to_string(half) + " point " + std::to_string(i));
        EXPECT_TRUE(est[std::size_t(i)].converged);
        EXPECT_LE(est[std::size_t(i)].std_error_total.x, 0.00501f * expected);
      }
      if (double_sided)
        expectWithin3Sigma(est[2].total, est[2].std_error_total, glm::vec3(polygonIrradiance(p[2], n[2], quad, l)),
                           "from above, double-sided");
      else
        EXPECT_EQ(est[2].total, glm::vec3(0.0f)) << "the back of a single-sided emitter is black";
    }
  }
}

// Escaping rays see the sky: a uniform sky over an open plane gives pi L exactly, and an SH
// sky gives E(n) = sum_lm A_l L_lm Y_lm(n) (the clamped-cosine convolution of docs/sh.md)
// wherever nothing blocks it.
TEST(Reference, SkyMatchesUniformAndShIrradiance) {
  {
    Scene s;
    addQuad(s, {-50, -50, 0}, {50, -50, 0}, {50, 50, 0}, {-50, 50, 0}, addMaterial(s, glm::vec3(0.0f)));
    relight::LightSet lights;
    ASSERT_TRUE(lights.setSky({glm::vec3(0.5f, 1.0f, 2.0f), std::nullopt}));
    auto w = World::make(std::move(s), lights);
    ASSERT_TRUE(w);
    const auto e = w->run({glm::vec3(0.0f)}, {glm::vec3(0, 0, 1)}).at(0);
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(e.total[c], kPi * glm::vec3(0.5f, 1.0f, 2.0f)[c], 1e-4f);
  }
  Scene s;
  // One tiny triangle 1 km away: the accel needs geometry, the sky must stay unblocked.
  MeshInstance speck;
  speck.positions = {{1000, 0, 0}, {1000, 0.001f, 0}, {1000, 0, 0.001f}};
  speck.normals = {{-1, 0, 0}, {-1, 0, 0}, {-1, 0, 0}};
  speck.indices = {0, 1, 2};
  s.meshes.push_back(speck);
  relight::Sky sky;
  std::array<glm::vec3, 9> coeffs{};
  coeffs[0] = glm::vec3(3.0f, 2.0f, 1.0f);  // L_00: positive radiance everywhere below
  coeffs[1] = glm::vec3(0.5f, 0.0f, -0.2f);
  coeffs[2] = glm::vec3(0.8f, 0.4f, 0.3f);
  coeffs[3] = glm::vec3(-0.3f, 0.2f, 0.0f);
  coeffs[6] = glm::vec3(0.3f, -0.2f, 0.1f);
  coeffs[8] = glm::vec3(0.1f, 0.2f, -0.1f);
  sky.sh = coeffs;
  relight::LightSet lights;
  ASSERT_TRUE(lights.setSky(sky));
  auto w = World::make(std::move(s), lights);
  ASSERT_TRUE(w);
  TestRng rng{4};
  std::vector<glm::vec3> p, n;
  for (int i = 0; i < 4; ++i) {
    p.push_back(glm::vec3(rng.next(), rng.next(), rng.next()));
    n.push_back(rng.direction());
  }
  const auto est = w->run(p, n);
  for (std::size_t i = 0; i < est.size(); ++i) {
    float basis[9];
    sh::evalBasis<3>(n[i], basis);
    glm::vec3 expected(0.0f);
    for (int k = 0; k < 9; ++k) expected += sh::kIrradianceBandFactors[std::size_t(sh::bandOf(k))] * coeffs[std::size_t(k)] * basis[k];
    expectWithin3Sigma(est[i].total, est[i].std_error_total, expected, "SH sky point " + std::to_string(i));
    EXPECT_EQ(est[i].indirect, glm::vec3(0.0f));
  }
}

// A room with everything at once: a point light, a spot, an emissive panel, coloured walls,
// an occluding block and a window to the sky.
Scene mixedRoom() {
  Scene s;
  const int wall = addMaterial(s, glm::vec3(0.7f, 0.6f, 0.5f));
  const int panel = addMaterial(s, glm::vec3(0.2f), glm::vec3(4.0f, 3.0f, 2.0f));
  const int block = addMaterial(s, glm::vec3(0.3f, 0.8f, 0.3f));
  // Room without a ceiling: the sky looks in from above.
  addQuad(s, {0, 0, 0}, {4, 0, 0}, {4, 4, 0}, {0, 4, 0}, wall);
  addQuad(s, {0, 0, 0}, {0, 0, 3}, {4, 0, 3}, {4, 0, 0}, wall);
  addQuad(s, {0, 4, 0}, {4, 4, 0}, {4, 4, 3}, {0, 4, 3}, wall);
  addQuad(s, {0, 0, 0}, {0, 4, 0}, {0, 4, 3}, {0, 0, 3}, wall);
  addQuad(s, {4, 0, 0}, {4, 0, 3}, {4, 4, 3}, {4, 4, 0}, wall);
  addQuad(s, {3.99f, 1, 1}, {3.99f, 1, 2}, {3.99f, 2, 2}, {3.99f, 2, 1}, panel);
  addBox(s, {1.5f, 1.5f, 0}, {2.5f, 2.5f, 1}, false, block);
  return s;
}

relight::LightSet mixedLights() {
  relight::LightSet lights;
  scene::Light point;
  point.intensity = 20.0f;
  point.position = {1.0f, 3.0f, 2.5f};
  EXPECT_TRUE(lights.add({"point", point, true}));
  scene::Light spot;
  spot.kind = scene::Light::Kind::kSpot;
  spot.intensity = 50.0f;
  spot.position = {3.0f, 1.0f, 2.8f};
  spot.direction = glm::normalize(glm::vec3(-0.3f, 0.2f, -1.0f));
  spot.inner_cone_angle = 0.3f;
  spot.outer_cone_angle = 0.6f;
  EXPECT_TRUE(lights.add({"spot", spot, false}));
  EXPECT_TRUE(lights.setSky({glm::vec3(0.2f, 0.3f, 0.5f), std::nullopt}));
  return lights;
}

std::vector<glm::vec3> mixedPoints(std::vector<glm::vec3>& normals) {
  TestRng rng{5};
  std::vector<glm::vec3> p;
  for (int i = 0; i < 6; ++i) {
    p.push_back(glm::vec3(0.2f + 3.6f * rng.next(), 0.2f + 3.6f * rng.next(), 1.2f + 1.5f * rng.next()));
    normals.push_back(rng.direction());
  }
  p.push_back({0.5f, 0.5f, 0.0f});  // floor texels
  normals.push_back({0, 0, 1});
  p.push_back({2.0f, 2.0f, 1.0f});  // on top of the block
  normals.push_back({0, 0, 1});
  return p;
}

TEST(Reference, DirectAndIndirectSumToTotal) {
  auto w = World::make(mixedRoom(), mixedLights());
  ASSERT_TRUE(w);
  std::vector<glm::vec3> n;
  const auto p = mixedPoints(n);
  ReferenceOptions o;
  o.target_rel_error = 0.05f;
  for (const auto& e : w->run(p, n, o)) {
    EXPECT_EQ(e.total, e.direct + e.indirect);
    for (int c = 0; c < 3; ++c) {
      EXPECT_GE(e.direct[c], e.direct_punctual[c]);  // plus emitters and sky seen directly
      EXPECT_GT(e.indirect[c], 0.0f);
      EXPECT_GT(e.std_error_indirect[c], 0.0f);
      EXPECT_LE(e.std_error_total[c], 0.0501f * std::max(e.total.x, std::max(e.total.y, e.total.z)));
    }
    EXPECT_TRUE(e.converged);
    EXPECT_GE(e.samples, 64u);
    EXPECT_GT(e.rays, e.samples);
  }
}

TEST(Reference, BitIdenticalForAnyThreadCount) {
  auto w = World::make(mixedRoom(), mixedLights());
  ASSERT_TRUE(w);
  std::vector<glm::vec3> n;
  const auto p = mixedPoints(n);
  ReferenceOptions o;
  o.target_rel_error = 0.05f;
  o.seed = 42;
  const auto runWith = [&](int threads) {
    tbb::global_control limit(tbb::global_control::max_allowed_parallelism, std::size_t(threads));
    return w->run(p, n, o);
  };
  const auto one = runWith(1), two = runWith(2);
  ASSERT_EQ(one.size(), two.size());
  for (std::size_t i = 0; i < one.size(); ++i) {
    EXPECT_EQ(std::memcmp(&one[i].total, &two[i].total, sizeof(glm::vec3)), 0) << "point " << i;
    EXPECT_EQ(std::memcmp(&one[i].indirect, &two[i].indirect, sizeof(glm::vec3)), 0) << "point " << i;
    EXPECT_EQ(std::memcmp(&one[i].std_error_total, &two[i].std_error_total, sizeof(glm::vec3)), 0);
    EXPECT_EQ(one[i].samples, two[i].samples);
    EXPECT_EQ(one[i].rays, two[i].rays);
  }
  o.seed = 43;  // another seed: another (equally valid) estimate
  const auto other = w->run(p, n, o);
  EXPECT_NE(other[0].total, one[0].total);
}

// Emissive overrides of the light set apply as in the relight: kRadiance replaces (and makes
// a non-emissive material emit), kScale multiplies the scene's emission.
TEST(Reference, EmissiveOverridesApply) {
  for (const auto mode : {relight::EmissiveOverride::Mode::kRadiance, relight::EmissiveOverride::Mode::kScale}) {
    Scene s;
    const bool radiance = mode == relight::EmissiveOverride::Mode::kRadiance;
    const int m = addMaterial(s, glm::vec3(0.0f), radiance ? glm::vec3(0.0f) : glm::vec3(1.0f, 2.0f, 3.0f));
    addBox(s, glm::vec3(0.0f), glm::vec3(1.0f), true, m);
    relight::LightSet lights;
    ASSERT_TRUE(lights.setEmissive({m, mode, glm::vec3(2.0f, 0.5f, 1.0f)}));
    auto w = World::make(std::move(s), lights);
    ASSERT_TRUE(w);
    const glm::vec3 le = radiance ? glm::vec3(2.0f, 0.5f, 1.0f) : glm::vec3(2.0f, 1.0f, 3.0f);
    const auto e = w->run({glm::vec3(0.5f)}, {glm::vec3(1, 0, 0)}).at(0);
    expectWithin3Sigma(e.total, e.std_error_total, kPi * le, radiance ? "kRadiance" : "kScale");
  }
}

TEST(Reference, RejectsInvalidOptionsAndQueries) {
  Scene s;
  addBox(s, glm::vec3(0.0f), glm::vec3(1.0f), true, addMaterial(s, glm::vec3(0.5f), glm::vec3(1.0f)));
  auto w = World::make(std::move(s));
  ASSERT_TRUE(w);
  const std::vector<glm::vec3> p = {glm::vec3(0.5f)}, n = {glm::vec3(0, 0, 1)};
  const auto rejects = [&](ReferenceOptions o, const std::string& field) {
    auto r = w->renderer->irradiance({p, n}, o);
    ASSERT_FALSE(r) << field;
    EXPECT_EQ(r.status().code(), Code::kInvalidInput);
    EXPECT_NE(r.status().message().find(field), std::string::npos) << r.status().message();
  };
  ReferenceOptions o;
  o.target_rel_error = std::nanf("");
  rejects(o, "target_rel_error");
  o = {};
  o.target_rel_error = -0.1f;
  rejects(o, "target_rel_error");
  o = {};
  o.min_samples = 0;
  rejects(o, "min_samples");
  o = {};
  o.max_samples = 10;
  rejects(o, "max_samples");
  o = {};
  o.time_budget_s = -1.0;
  rejects(o, "time_budget_s");
  o = {};
  o.time_budget_s = std::numeric_limits<double>::infinity();
  rejects(o, "time_budget_s");
  o = {};
  o.max_bounces = -1;
  rejects(o, "max_bounces");

  const std::vector<glm::vec3> two = {glm::vec3(0.5f), glm::vec3(0.4f)};
  EXPECT_FALSE(w->renderer->irradiance({two, n}, {}));
  const std::vector<glm::vec3> zero = {glm::vec3(0.0f)};
  auto r = w->renderer->irradiance({p, zero}, {});
  ASSERT_FALSE(r);
  EXPECT_NE(r.status().message().find("query.normal[0]"), std::string::npos);
  const std::vector<glm::vec3> nan = {glm::vec3(0.5f, std::nanf(""), 0.5f)};
  r = w->renderer->irradiance({nan, n}, {});
  ASSERT_FALSE(r);
  EXPECT_NE(r.status().message().find("query.position[0]"), std::string::npos);
  // An empty query is valid and returns nothing.
  auto empty = w->renderer->irradiance({}, {});
  ASSERT_TRUE(empty);
  EXPECT_TRUE(empty->empty());
}

TEST(Reference, CreateRejectsMismatchedAccelAndOverrides) {
  Scene a;
  addBox(a, glm::vec3(0.0f), glm::vec3(1.0f), true, addMaterial(a, glm::vec3(0.5f)));
  auto w = World::make(std::move(a));
  ASSERT_TRUE(w);
  Scene b;
  addQuad(b, {0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}, addMaterial(b, glm::vec3(0.5f)));
  auto r = ReferenceRenderer::create(b, *w->accel, {});
  ASSERT_FALSE(r);
  EXPECT_EQ(r.status().code(), Code::kInvalidInput);

  relight::LightSet lights;
  ASSERT_TRUE(lights.setEmissive({5, relight::EmissiveOverride::Mode::kScale, glm::vec3(1.0f)}));
  r = ReferenceRenderer::create(w->scene, *w->accel, lights);
  ASSERT_FALSE(r);
  EXPECT_NE(r.status().message().find("emissive[0].material"), std::string::npos);
}

// A time budget stops the call (results not converged, but with samples and an honest error);
// a cancelled progress stops it with an error.
TEST(Reference, TimeBudgetAndCancellationStopEarly) {
  Scene s;
  addBox(s, glm::vec3(0.0f), glm::vec3(1.0f), true, addMaterial(s, glm::vec3(0.9f), glm::vec3(1.0f)));
  auto w = World::make(std::move(s));
  ASSERT_TRUE(w);
  std::vector<glm::vec3> p(16, glm::vec3(0.5f)), n(16, glm::vec3(0, 0, 1));
  ReferenceOptions o;
  o.target_rel_error = 1e-6f;
  o.max_samples = 1 << 30;
  o.time_budget_s = 0.2;
  const auto start = std::chrono::steady_clock::now();
  const auto est = w->run(p, n, o);
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  EXPECT_LT(seconds, 2.0);
  ASSERT_EQ(est.size(), 16u);
  for (const auto& e : est) {
    EXPECT_FALSE(e.converged);
    EXPECT_GE(e.samples, 64u);
    expectWithin3Sigma(e.total, e.std_error_total, glm::vec3(kPi / 0.1f), "budgeted furnace");
  }

  struct Cancelled final : Progress {
    void begin(std::string_view, std::size_t) override {}
    void update(std::size_t) override {}
    void end() override {}
    bool cancelled() const override { return true; }
  } cancel;
  auto r = w->renderer->irradiance({p, n}, {}, &cancel);
  ASSERT_FALSE(r);
  EXPECT_NE(r.status().message().find("cancelled"), std::string::npos);
}

}  // namespace
}  // namespace lightlink::reference
