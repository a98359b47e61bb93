// Alpha cut-outs and cast_shadows in the Accel (issue 46): a MASK checker card blocks rays
// only on its opaque squares, for every query form; BLEND is a mask at 0.5; a mesh that casts
// no shadows is skipped by occlusion queries and still hit by intersect.
#include <cstdint>
#include <vector>

#include <gtest/gtest.h>

#include "core/rt/accel.h"
#include "tests/common/scene_builders.h"

namespace lightlink::rt {
namespace {

// An 8 x 8 checker of alpha 0 / 255 (NEAREST), opaque where (x + y) is even.
scene::Texture checker() {
  scene::Texture t;
  t.width = t.height = 8;
  t.channels = 4;
  t.nearest = true;
  t.rgba8.assign(8 * 8 * 4, 200);
  for (int y = 0; y < 8; ++y)
    for (int x = 0; x < 8; ++x) t.rgba8[4 * (y * 8 + x) + 3] = (x + y) % 2 == 0 ? 255 : 0;
  return t;
}

// A unit card in z = 0 facing +z, uv0 = (x, 1 - y), with `material`; a floor at z = -1 behind it.
scene::Scene cardScene(const scene::Material& material, bool card_casts_shadows = true) {
  scene::Scene s;
  s.textures.push_back(checker());
  s.materials.push_back(material);
  testing::addQuad(s, {0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}, 0);
  s.meshes.back().uv0 = {{0, 1}, {1, 1}, {1, 0}, {0, 0}};
  s.meshes.back().cast_shadows = card_casts_shadows;
  testing::addQuad(s, {-1, -1, -1}, {2, -1, -1}, {2, 2, -1}, {-1, 2, -1});
  testing::finishScene(s);
  return s;
}

scene::Material maskMaterial() {
  scene::Material m;
  m.alpha_mode = scene::Material::AlphaMode::kMask;
  m.alpha_cutoff = 0.5f;
  m.base_color_texture.texture = 0;
  return m;
}

// 64 x 64 rays down -z through the card, one per cell centre.
std::vector<Ray> raysThroughCard() {
  std::vector<Ray> rays;
  for (int j = 0; j < 64; ++j)
    for (int i = 0; i < 64; ++i) {
      Ray r;
      r.origin = glm::vec3((i + 0.5f) / 64.0f, (j + 0.5f) / 64.0f, 1.0f);
      r.dir = glm::vec3(0, 0, -1);
      r.tfar = 1.5f;  // reaches the card (t = 1), not the floor (t = 2)
      rays.push_back(r);
    }
  return rays;
}

bool opaqueSquare(const Ray& r) {
  const int x = int(r.origin.x * 8.0f), y = int((1.0f - r.origin.y) * 8.0f);
  return (x + y) % 2 == 0;
}

TEST(Cutout, MaskCheckerCardBlocksOnlyItsOpaqueSquaresForEveryQuery) {
  auto accel = Accel::build(cardScene(maskMaterial()));
  ASSERT_TRUE(accel) << accel.status().message();
  const auto rays = raysThroughCard();
  std::vector<std::uint8_t> packets(rays.size()), stream(rays.size());
  accel->occluded(rays, packets, Coherence::kCoherent);
  accel->occluded(rays, stream, Coherence::kIncoherent);
  std::vector<Hit> hits(rays.size());
  accel->intersect(rays, hits, Coherence::kCoherent);
  std::size_t blocked = 0, wrong = 0;
  for (std::size_t k = 0; k < rays.size(); ++k) {
    const bool expect = opaqueSquare(rays[k]);
    blocked += accel->occluded(rays[k]) ? 1 : 0;
    wrong += accel->occluded(rays[k]) != expect;
    wrong += bool(packets[k]) != expect;
    wrong += bool(stream[k]) != expect;
    wrong += hits[k].hit() != expect;
    wrong += accel->intersect(rays[k]).hit() != expect;
  }
  EXPECT_EQ(blocked, rays.size() / 2);  // a 50 % checker shadow
  EXPECT_EQ(wrong, 0u);
  // Through a hole the ray goes on to the floor behind.
  Ray through = rays[1];  // square (0, 7): transparent
  ASSERT_FALSE(opaqueSquare(through));
  through.tfar = 10.0f;
  const Hit h = accel->intersect(through);
  ASSERT_TRUE(h.hit());
  EXPECT_EQ(h.mesh, 1u);
  EXPECT_NEAR(h.t, 2.0f, 1e-4f);
}

TEST(Cutout, CutoffAndFactorDecideWithoutATexture) {
  scene::Material m;
  m.alpha_mode = scene::Material::AlphaMode::kMask;
  m.base_color_factor.w = 0.4f;
  m.alpha_cutoff = 0.5f;
  const Ray down{{0.5f, 0.5f, 1.0f}, 0.0f, {0, 0, -1}, 1.5f};
  EXPECT_FALSE(Accel::build(cardScene(m))->occluded(down));
  m.alpha_cutoff = 0.3f;
  EXPECT_TRUE(Accel::build(cardScene(m))->occluded(down));
  // BLEND: a mask at one half, whatever alphaCutoff says.
  m.alpha_mode = scene::Material::AlphaMode::kBlend;
  EXPECT_FALSE(Accel::build(cardScene(m))->occluded(down));
  m.base_color_factor.w = 0.7f;
  EXPECT_TRUE(Accel::build(cardScene(m))->occluded(down));
}

TEST(Cutout, ASheetThatCastsNoShadowsIsSkippedByShadowRaysOnly) {
  scene::Material blend;
  blend.alpha_mode = scene::Material::AlphaMode::kBlend;
  blend.base_color_factor.w = 0.8f;  // opaque enough to be hit
  auto accel = Accel::build(cardScene(blend, /*card_casts_shadows=*/false));
  ASSERT_TRUE(accel);
  const auto rays = raysThroughCard();
  std::vector<std::uint8_t> packets(rays.size());
  accel->occluded(rays, packets, Coherence::kCoherent);
  std::size_t blocked = 0, hit = 0;
  for (std::size_t k = 0; k < rays.size(); ++k) {
    blocked += accel->occluded(rays[k]) + packets[k];
    hit += accel->intersect(rays[k]).hit();
  }
  EXPECT_EQ(blocked, 0u);
  EXPECT_EQ(hit, rays.size());
}

}  // namespace
}  // namespace lightlink::rt
