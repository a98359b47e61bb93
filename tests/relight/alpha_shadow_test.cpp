// Issue 46, end to end through the loader and the baker's direct layer: a MASK checker card
// casts a checker shadow (about half the floor under it lit, each square as its alpha says),
// and an opaque-looking BLEND sheet with extras cast_shadows false casts none; the card's
// lightmap texels over its holes are invalid. The scene is
// tests/data/alpha/alpha_cards.gltf (scripts/scenes/alpha_cards.py): a 10 lux sun straight down.
#include <cstdio>

#include <gtest/gtest.h>

#include "core/scene/load.h"
#include "tests/common/testing.h"
#include "tests/relight/relight_fixture.h"

namespace lightlink::relight::testing {
namespace {

TEST(AlphaShadow, MaskCheckerCardCastsACheckerAndANoShadowSheetCastsNone) {
  auto scene = scene::loadScene((lightlink::testing::sourceDir() / "tests/data/alpha/alpha_cards.gltf").string());
  ASSERT_TRUE(scene) << scene.status().toString();
  precompute::PrecomputeOptions o = smallOptions();
  o.lightmap_resolution.reset();
  o.texel_size_m = 0.025f;  // 5 texels across a 12.5 cm checker square
  auto baked = Baked::make(std::move(*scene), o);
  ASSERT_TRUE(baked);
  RelightOptions ro;
  ro.max_bounces = 0;
  auto r = baked->relighter().relight(LightSet::fromSceneLights(baked->scene.lights), ro);
  ASSERT_TRUE(r) << r.status().toString();

  const auto& lm = baked->p.lightmap;
  std::uint32_t floor = 0;
  while (floor < baked->scene.meshes.size() && baked->scene.meshes[floor].name.rfind("floor", 0) != 0) ++floor;
  ASSERT_LT(floor, baked->scene.meshes.size());
  const float sun = 10.0f;
  std::size_t under_card = 0, lit_under_card = 0, deep = 0, deep_wrong = 0, under_sheet = 0, lit_under_sheet = 0;
  for (std::size_t c = 0; c < lm.size(); ++c) {
    if (!lm.valid[c] || lm.mesh[c] != floor) continue;
    const glm::vec3 p = lm.position[c];
    const bool lit = r->direct[lm.texel[c]].y > 0.5f * sun;
    if (p.x > 0.5f && p.x < 1.5f && p.z > -0.5f && p.z < 0.5f) {
      ++under_card;
      lit_under_card += lit;
      // Square (i, j) of the card's 8 x 8 checker (uv (0,0) at x = 0.5, z = -0.5) is opaque
      // where i + j is even; judge only texels well inside a square.
      const float u = (p.x - 0.5f) * 8.0f, v = (p.z + 0.5f) * 8.0f;
      const float fu = u - std::floor(u), fv = v - std::floor(v);
      if (fu > 0.25f && fu < 0.75f && fv > 0.25f && fv < 0.75f) {
        ++deep;
        const bool opaque = (int(u) + int(v)) % 2 == 0;
        deep_wrong += lit == opaque;
      }
    }
    if (p.x > 2.55f && p.x < 3.45f && p.z > -0.45f && p.z < 0.45f) {
      ++under_sheet;
      lit_under_sheet += lit;
    }
  }
  // The card's own texels over its holes are invalid (filled from the opaque squares).
  std::uint32_t card = 0;
  while (card < baked->scene.meshes.size() && baked->scene.meshes[card].name.rfind("checker_card", 0) != 0) ++card;
  ASSERT_LT(card, baked->scene.meshes.size());
  std::size_t card_texels = 0, card_invalid = 0;
  for (std::size_t c = 0; c < lm.size(); ++c) {
    if (lm.mesh[c] != card) continue;
    ++card_texels;
    card_invalid += !lm.valid[c];
  }
  std::printf("card texels %zu, %zu invalid over holes\n", card_texels, card_invalid);
  ASSERT_GT(card_texels, 500u);
  EXPECT_NEAR(double(card_invalid) / double(card_texels), 0.5, 0.1);
  ASSERT_GT(under_card, 500u);
  ASSERT_GT(deep, 100u);
  ASSERT_GT(under_sheet, 400u);  // valid floor texels under the sheet (499 with the footprint placement)
  const double coverage = 1.0 - double(lit_under_card) / double(under_card);
  std::printf("under the card %zu of %zu texels lit (coverage %.3f), %zu of %zu inside squares disagree; under the "
              "sheet %zu of %zu lit\n", lit_under_card, under_card, coverage, deep_wrong, deep, lit_under_sheet, under_sheet);
  EXPECT_NEAR(coverage, 0.5, 0.1) << lit_under_card << " of " << under_card << " texels lit under the card";
  EXPECT_LE(deep_wrong, deep / 50) << deep_wrong << " of " << deep << " texels inside a square disagree with its alpha";
  EXPECT_EQ(lit_under_sheet, under_sheet) << "the cast_shadows false sheet shadows the floor";
}

}  // namespace
}  // namespace lightlink::relight::testing
