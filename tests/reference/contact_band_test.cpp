#include "core/reference/contact_band.h"

#include <vector>

#include <gtest/gtest.h>

#include "tests/common/scene_builders.h"

namespace lightlink::reference {
namespace {

TEST(ContactBand, SurfacesAtAnAngleOrAboveCountCoplanarAndOpenEdgesDoNot) {
  scene::Scene s;
  // A floor of two coplanar quads (a seam at x = 1), a wall standing on it at x = 1.5 facing
  // -x, and a sheet 2 mm above the floor around x = 0.5, z = 1.5.
  testing::addQuad(s, {0, 0, 0}, {0, 0, 2}, {1, 0, 2}, {1, 0, 0});
  testing::addQuad(s, {1, 0, 0}, {1, 0, 2}, {2, 0, 2}, {2, 0, 0});
  testing::addQuad(s, {1.5f, 0, 0}, {1.5f, 0, 2}, {1.5f, 1, 2}, {1.5f, 1, 0});
  testing::addQuad(s, {0.3f, 0.002f, 1.3f}, {0.3f, 0.002f, 1.7f}, {0.7f, 0.002f, 1.7f}, {0.7f, 0.002f, 1.3f});
  testing::finishScene(s);
  auto accel = rt::Accel::build(s);
  ASSERT_TRUE(accel) << accel.status().message();
  const glm::vec3 up(0, 1, 0);
  const std::vector<glm::vec3> pos = {
      {1.45f, 0, 1.0f},   // floor 5 cm from the wall
      {1.2f, 0, 1.0f},    // floor 30 cm from it
      {0.99f, 0, 0.5f},   // floor at the coplanar seam
      {0.5f, 0, 1.5f},    // floor under the sheet
      {0.05f, 0, 0.5f},   // floor at its open outer edge
      {1.5f, 0.05f, 1.0f} // wall 5 cm above the floor
  };
  const std::vector<glm::vec3> nrm = {up, up, up, up, up, {-1, 0, 0}};
  const std::vector<float> radius(pos.size(), 0.1f);
  const auto band = nearContact(*accel, pos, nrm, radius);
  EXPECT_EQ(band, (std::vector<std::uint8_t>{1, 0, 0, 1, 0, 1}));
}

TEST(ContactBand, TexelSizeFromWorldAndLightmapAreas) {
  scene::MeshInstance m;
  m.positions = {{0, 0, 0}, {0, 0, 1}, {1, 0, 1}, {1, 0, 0}};
  m.uv1 = {{0, 0}, {0, 0.5f}, {0.5f, 0.5f}, {0.5f, 0}};
  m.indices = {0, 1, 2, 0, 2, 3};
  // A 1 m square on 32 x 32 texels of a 64 x 64 atlas.
  EXPECT_NEAR(texelSizeOnTriangle(m, 0, 64, 64), 1.0f / 32.0f, 1e-6f);
  EXPECT_NEAR(texelSizeOnTriangle(m, 1, 64, 64), 1.0f / 32.0f, 1e-6f);
  m.uv1.clear();
  EXPECT_EQ(texelSizeOnTriangle(m, 0, 64, 64), 0.0f);
}

}  // namespace
}  // namespace lightlink::reference
