// The emitters' direct light at the surfels (docs/relight.md, the surfel_emitter pass).
// Received only through the first bounce gather from the lightmap caches' links, a small lamp
// is blurred into coarse cut nodes and 3-band SH: on the Cornell box the surfels would get 0.72
// of the reference's emitter light. It is sampled on the emitting triangles like a texel's
// direct light, and this test holds it to the closed form of a parallel rectangle's form
// factor.
#include <cmath>
#include <numbers>

#include <gtest/gtest.h>

#include "tests/relight/relight_fixture.h"

namespace lightlink::relight {
namespace {

using namespace lightlink::relight::testing;
constexpr double kPi = std::numbers::pi;

// Form factor from a point to the rectangle [0, a] x [0, b] in a parallel plane at distance c,
// the point below the corner (0, 0); odd in a and in b, so signed sums give any rectangle.
double cornerFormFactor(double a, double b, double c) {
  const double x = a / c, y = b / c;
  const double sx = std::sqrt(1.0 + x * x), sy = std::sqrt(1.0 + y * y);
  return (x / sx * std::atan(y / sx) + y / sy * std::atan(x / sy)) / (2.0 * kPi);
}

// Irradiance at (px, 0, pz) (normal +y) from a downward-facing Lambertian emitter of radiance
// le covering [x0, x1] x [z0, z1] at height h: E = pi * le * F.
double lampIrradiance(double px, double pz, double x0, double x1, double z0, double z1, double h, double le) {
  const double f = cornerFormFactor(x1 - px, z1 - pz, h) - cornerFormFactor(x0 - px, z1 - pz, h) -
                   cornerFormFactor(x1 - px, z0 - pz, h) + cornerFormFactor(x0 - px, z0 - pz, h);
  return kPi * le * f;
}

TEST(SurfelEmitter, FloorSurfelsReceiveTheLampsDirectLight) {
  constexpr float kRho = 0.5f, kLe = 2.0f, kH = 0.5f;
  constexpr float x0 = 0.8f, x1 = 1.2f, z0 = 0.8f, z1 = 1.2f;
  scene::Scene s;
  const int floor = addMaterial(s, glm::vec3(kRho));
  // A black lamp: it reflects nothing back, so the floor's light is the lamp's direct alone
  // after any number of bounces (the floor is flat and sees no other floor).
  const int lamp = addMaterial(s, glm::vec3(0.0f), glm::vec3(kLe));
  addQuad(s, {0, 0, 0}, {0, 0, 2}, {2, 0, 2}, {2, 0, 0}, floor);          // faces +y
  addQuad(s, {x0, kH, z0}, {x1, kH, z0}, {x1, kH, z1}, {x0, kH, z1}, lamp);  // faces -y
  auto baked = Baked::make(std::move(s), smallOptions());
  ASSERT_TRUE(baked);
  Relighter r = baked->relighter();
  const auto& sf = baked->p.surfels;
  for (const int bounces : {0, 1}) {
    auto res = r.relight(LightSet{}, {.max_bounces = bounces, .bounce_threshold = 0.0f});
    ASSERT_TRUE(res) << res.status().toString();
    double got = 0.0, want = 0.0, err2 = 0.0;
    int n = 0;
    for (std::size_t i = 0; i < sf.size(); ++i) {
      if (sf.normal[i].y < 0.5f) continue;  // floor surfels only
      const double e = lampIrradiance(sf.position[i].x, sf.position[i].z, x0, x1, z0, z1, kH, kLe);
      const double b = res->surfel_radiosity[i].x / kRho;
      got += b, want += e, err2 += (b - e) * (b - e) / (e * e);
      ++n;
    }
    ASSERT_GT(n, 500);
    // Energy within 2 % (16 samples per surfel: the mean's noise is ~0.3 %), each surfel within
    // its own sampling noise on average.
    EXPECT_NEAR(got / want, 1.0, 0.02) << "bounces " << bounces;
    EXPECT_LT(std::sqrt(err2 / n), 0.25) << "bounces " << bounces;
  }
}

}  // namespace
}  // namespace lightlink::relight
