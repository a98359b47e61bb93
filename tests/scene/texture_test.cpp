// Texture::sampleSrgb: texel centres, bilinear filtering in linear space, the three glTF
// wrap modes and nearest filtering, on a 2x2 texture with known sRGB codes.
#include <gtest/gtest.h>

#include "core/scene/scene.h"

namespace lightlink::scene {
namespace {

// sRGB 8-bit code -> linear, IEC 61966-2-1 reference values.
constexpr float kLin0 = 0.0f;
constexpr float kLin10 = 0.0030353f;   // linear segment (c / 12.92)
constexpr float kLin64 = 0.0512695f;
constexpr float kLin128 = 0.2158605f;
constexpr float kLin200 = 0.5775804f;
constexpr float kLin255 = 1.0f;

// Row 0 (v near 0): [grey 128, grey 255]; row 1: [grey 0, (200, 64, 10)]. Alpha 51 everywhere
// except the last texel (255); alpha is linear.
Texture twoByTwo(int wrap = 10497) {
  Texture t;
  t.width = 2;
  t.height = 2;
  t.rgba8 = {128, 128, 128, 51, 255, 255, 255, 51, 0, 0, 0, 51, 200, 64, 10, 255};
  t.wrap_s = t.wrap_t = wrap;
  return t;
}

void expectRgba(glm::vec4 actual, glm::vec4 expected, float tol = 2e-6f) {
  EXPECT_NEAR(actual.x, expected.x, tol) << "r";
  EXPECT_NEAR(actual.y, expected.y, tol) << "g";
  EXPECT_NEAR(actual.z, expected.z, tol) << "b";
  EXPECT_NEAR(actual.w, expected.w, tol) << "a";
}

TEST(TextureSample, TexelCentresDecodeSrgbExactly) {
  const Texture t = twoByTwo();
  expectRgba(t.sampleSrgb({0.25f, 0.25f}), {kLin128, kLin128, kLin128, 0.2f});
  expectRgba(t.sampleSrgb({0.75f, 0.25f}), {kLin255, kLin255, kLin255, 0.2f});
  expectRgba(t.sampleSrgb({0.25f, 0.75f}), {kLin0, kLin0, kLin0, 0.2f});
  expectRgba(t.sampleSrgb({0.75f, 0.75f}), {kLin200, kLin64, kLin10, 1.0f});
}

// An RGB8 texture (an opaque material's: no alpha kept) samples the same colours, alpha 1.
TEST(TextureSample, RgbTexturesSampleAsOpaque) {
  Texture t = twoByTwo();
  t.channels = 3;
  t.rgba8 = {128, 128, 128, 255, 255, 255, 0, 0, 0, 200, 64, 10};
  expectRgba(t.sampleSrgb({0.25f, 0.25f}), {kLin128, kLin128, kLin128, 1.0f});
  expectRgba(t.sampleSrgb({0.75f, 0.25f}), {kLin255, kLin255, kLin255, 1.0f});
  expectRgba(t.sampleSrgb({0.25f, 0.75f}), {kLin0, kLin0, kLin0, 1.0f});
  expectRgba(t.sampleSrgb({0.75f, 0.75f}), {kLin200, kLin64, kLin10, 1.0f});
  t.rgba8.pop_back();  // too short for 2x2 RGB: treated as not decoded, white
  expectRgba(t.sampleSrgb({0.25f, 0.25f}), glm::vec4(1.0f));
}

TEST(TextureSample, BilinearAveragesLinearValues) {
  const Texture t = twoByTwo(33071);  // clamp, so only the four texels contribute
  const float mid = (kLin128 + kLin255) / 2.0f;
  expectRgba(t.sampleSrgb({0.5f, 0.25f}), {mid, mid, mid, 0.2f});
  const glm::vec4 centre = t.sampleSrgb({0.5f, 0.5f});
  expectRgba(centre, {(kLin128 + kLin255 + kLin0 + kLin200) / 4, (kLin128 + kLin255 + kLin0 + kLin64) / 4,
                      (kLin128 + kLin255 + kLin0 + kLin10) / 4, (0.2f * 3 + 1.0f) / 4});
}

TEST(TextureSample, RepeatWrapsAcrossEdges) {
  const Texture t = twoByTwo(10497);
  expectRgba(t.sampleSrgb({1.25f, -0.75f}), t.sampleSrgb({0.25f, 0.25f}));
  expectRgba(t.sampleSrgb({-7.75f, 3.75f}), t.sampleSrgb({0.25f, 0.75f}));
  // At u = 0 the left edge blends texel 0 with texel 1 (its neighbour across the seam).
  const float seam = (kLin128 + kLin255) / 2.0f;
  expectRgba(t.sampleSrgb({0.0f, 0.25f}), {seam, seam, seam, 0.2f});
}

TEST(TextureSample, ClampHoldsEdgeTexels) {
  const Texture t = twoByTwo(33071);
  expectRgba(t.sampleSrgb({-5.0f, 0.25f}), {kLin128, kLin128, kLin128, 0.2f});
  expectRgba(t.sampleSrgb({1e9f, 1e9f}), {kLin200, kLin64, kLin10, 1.0f});
  expectRgba(t.sampleSrgb({0.0f, 0.25f}), {kLin128, kLin128, kLin128, 0.2f});
}

TEST(TextureSample, MirroredRepeatReflects) {
  const Texture t = twoByTwo(33648);
  // u in [1, 2) mirrors: 1.25 reads like 0.75, 1.75 like 0.25; v = -0.25 reads like 0.25.
  expectRgba(t.sampleSrgb({1.25f, 0.25f}), t.sampleSrgb({0.75f, 0.25f}));
  expectRgba(t.sampleSrgb({1.75f, -0.25f}), t.sampleSrgb({0.25f, 0.25f}));
  expectRgba(t.sampleSrgb({2.25f, 0.25f}), t.sampleSrgb({0.25f, 0.25f}));
}

TEST(TextureSample, NearestPicksOneTexel) {
  Texture t = twoByTwo(33071);
  t.nearest = true;
  expectRgba(t.sampleSrgb({0.49f, 0.1f}), {kLin128, kLin128, kLin128, 0.2f});
  expectRgba(t.sampleSrgb({0.51f, 0.9f}), {kLin200, kLin64, kLin10, 1.0f});
}

TEST(TextureSample, UndecodedTextureIsWhite) {
  Texture t;
  expectRgba(t.sampleSrgb({0.3f, 0.3f}), glm::vec4(1.0f));
}

}  // namespace
}  // namespace lightlink::scene
