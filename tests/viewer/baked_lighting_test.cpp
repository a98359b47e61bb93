#include "clients/viewer/baked_lighting.h"

#include <array>
#include <cmath>
#include <numbers>

#include <gtest/gtest.h>

#include "core/sh/sh.h"

namespace lightlink::viewer {
namespace {

constexpr float kPi = std::numbers::pi_v<float>;

// A 2x2 lightmap, 1 band: texel t holds a constant radiance L_t (L00 = L sqrt(4 pi)), so
// its irradiance is pi * L_t for any normal.
BakedLighting twoByTwo(std::array<float, 4> radiance, std::array<float, 4> valid) {
  BakedLighting b;
  b.bands = 1;
  b.width = b.height = 2;
  for (int t = 0; t < 4; ++t) {
    const float c = radiance[t] * std::sqrt(4.0f * kPi);
    b.lightmap_sh.insert(b.lightmap_sh.end(), {c, c, c});
    b.direct.push_back(glm::vec3(0.0f));
    b.valid.push_back(valid[t]);
  }
  return b;
}

TEST(BakedLighting, BilinearBetweenTexelCentres) {
  const BakedLighting b = twoByTwo({1, 2, 3, 4}, {1, 1, 1, 1});
  glm::vec3 e;
  ASSERT_TRUE(b.sampleLightmap({0.5f, 0.5f}, {0, 0, 1}, e));  // the middle: mean of all four
  EXPECT_NEAR(e.x, kPi * 2.5f, 1e-4f);
  ASSERT_TRUE(b.sampleLightmap({0.25f, 0.25f}, {0, 0, 1}, e));  // texel 0's centre
  EXPECT_NEAR(e.y, kPi * 1.0f, 1e-4f);
}

TEST(BakedLighting, InvalidTexelsCarryNoWeight) {
  // Texel 3 is invalid and black: the middle must average only the three valid ones.
  const BakedLighting b = twoByTwo({1, 2, 3, 0}, {1, 1, 1, 0});
  glm::vec3 e;
  ASSERT_TRUE(b.sampleLightmap({0.5f, 0.5f}, {0, 1, 0}, e));
  EXPECT_NEAR(e.z, kPi * 2.0f, 1e-4f);
  const BakedLighting none = twoByTwo({1, 2, 3, 4}, {0, 0, 0, 0});
  EXPECT_FALSE(none.sampleLightmap({0.5f, 0.5f}, {0, 1, 0}, e));
}

TEST(BakedLighting, GridTrilinearSkipsInvalidPoints) {
  BakedLighting b;
  b.bands = 1;
  b.has_grid = true;
  b.dims = {2, 2, 2};
  b.origin = glm::vec3(0.0f);
  b.spacing_m = 1.0f;
  for (int i = 0; i < 8; ++i) {
    const float c = float(i) * std::sqrt(4.0f * kPi);
    b.grid_sh.insert(b.grid_sh.end(), {c, c, c});
    b.grid_valid.push_back(i == 7 ? 0.0f : 1.0f);
  }
  glm::vec3 e;
  ASSERT_TRUE(b.sampleGrid({0.0f, 0.0f, 0.0f}, {1, 0, 0}, e));
  EXPECT_NEAR(e.x, 0.0f, 1e-4f);
  ASSERT_TRUE(b.sampleGrid({1.0f, 0.0f, 0.0f}, {1, 0, 0}, e));  // point 1
  EXPECT_NEAR(e.x, kPi * 1.0f, 1e-4f);
  ASSERT_TRUE(b.sampleGrid({0.5f, 0.5f, 0.5f}, {1, 0, 0}, e));  // mean of points 0..6
  EXPECT_NEAR(e.x, kPi * 3.0f, 1e-3f);
}

TEST(BakedLighting, MissingBakeIsAnErrorNamingTheFile) {
  auto b = loadBakedLighting("/no/such/bake");
  ASSERT_FALSE(b);
  EXPECT_NE(b.status().message().find("lightmap.exr"), std::string::npos) << b.status().message();
}

}  // namespace
}  // namespace lightlink::viewer
