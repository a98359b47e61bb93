// Temporal stability (issue 48), by the roughness metric of bench/common/flicker.h: a point
// light moving smoothly over a floor, a wall and a block gives an indirect that changes
// smoothly wherever the surfels' light does, whatever the cuts its caches link, and a direct
// layer that does except where the block's hard shadow edge flips texels; the surfels' own
// shadow rays make the indirect pop (a known limit); the metric fails a sequence with a jump.
#include "bench/common/flicker.h"

#include <cmath>

#include <gtest/gtest.h>

#include "core/scene/light_eval.h"
#include "tests/relight/relight_fixture.h"

namespace lightlink::relight {
namespace {

using namespace lightlink::relight::testing;
using bench::FlickerFrames;
using bench::measureFlicker;

// Frames of f(texel, u) for u in [0, 1] at 2 * steps + 1 points; every texel has a value.
template <typename F>
FlickerFrames synthetic(std::size_t texels, int steps, F f) {
  FlickerFrames out;
  out.texels = texels;
  out.has_value.assign(texels, 1);
  for (int t = 0; t <= 2 * steps; ++t)
    for (std::size_t i = 0; i < texels; ++i) out.values.push_back(f(i, float(t) / float(2 * steps)));
  return out;
}

// `frames` with every texel's value raised by `jump` of its mean from the middle frame on.
FlickerFrames withJump(FlickerFrames f, float jump) {
  for (std::size_t i = 0; i < f.texels; ++i) {
    double mean = 0.0;
    for (std::size_t t = 0; t < f.frames(); ++t) mean += f.at(t, i);
    mean /= double(f.frames());
    for (std::size_t t = f.frames() / 2; t < f.frames(); ++t) f.values[t * f.texels + i] += float(jump * mean);
  }
  return f;
}

TEST(Flicker, TheRoughnessRatioTellsSmoothFromKinkedFromJumps) {
  // Falloff from a light passing over a row of texels: smooth, ratio 1/2.
  auto falloff = [](std::size_t i, float u) {
    const float x = 0.1f * float(i) - 0.4f * u;
    return 1.0f / (1.0f + x * x);
  };
  const auto smooth = measureFlicker(synthetic(16, 12, falloff));
  EXPECT_EQ(smooth.lit_texels, 16u);
  EXPECT_NEAR(smooth.ratio, 0.5, 0.05);
  EXPECT_EQ(smooth.popping_texels, 0u);
  EXPECT_LT(smooth.fine.p999_d2, 0.6 * smooth.coarse.p999_d2);
  // A kink (a clamped cosine) inside the path: about 1/sqrt(2); nothing pops. (A kink within
  // a step of either end can: one step cannot tell it from a jump.)
  const auto kink = measureFlicker(synthetic(16, 12, [](std::size_t i, float u) {
    return 0.2f + std::max(0.0f, 0.2f + 0.04f * float(i) - u);
  }));
  EXPECT_GT(kink.ratio, 0.6);
  EXPECT_LT(kink.ratio, 0.85);
  EXPECT_EQ(kink.popping_texels, 0u);
  // A jump of 5 % of the mean: every texel pops, the ratio stays near 1.
  const auto jump = measureFlicker(withJump(synthetic(16, 12, falloff), 0.05f));
  EXPECT_GT(jump.ratio, 0.9);
  EXPECT_EQ(jump.popping_texels, 16u);
  ASSERT_FALSE(jump.worst.empty());
  EXPECT_GE(jump.worst.front().frame, 11u);  // the jump is between frames 11 and 12
  EXPECT_LE(jump.worst.front().frame, 12u);
  EXPECT_TRUE(jump.worst.front().pops);
}

TEST(Flicker, DarkTexelsAndTexelsWithoutAValueAreNotCounted) {
  auto f = synthetic(4, 4, [](std::size_t i, float u) { return i == 0 ? 0.0f : float(i) + u; });
  f.has_value[3] = 0;
  const auto m = measureFlicker(f);
  EXPECT_EQ(m.texels_with_value, 3u);
  EXPECT_EQ(m.lit_texels, 2u);
}

// A floor, a back wall and a block on the floor; a point light above them moves 0.25 m (4 %
// of the scene's size) sideways in 24 steps, relit with the daemon's default options. Twice:
// with the relight's own surfel light, and with the surfels lit without shadow rays (given
// through RelightOptions::surfel_irradiance), which is smooth in the light's position.
struct LightPath {
  static constexpr int kSteps = 12;
  std::unique_ptr<Baked> baked;
  FlickerFrames direct, indirect;                  // the relight's own surfel light
  FlickerFrames smooth_direct, smooth_indirect;    // surfels lit without shadow rays

  explicit LightPath(int rays = RelightOptions{}.surfel_shadow_rays) {
    scene::Scene s;
    const int grey = addMaterial(s, glm::vec3(0.6f));
    const int red = addMaterial(s, glm::vec3(0.7f, 0.2f, 0.2f));
    addQuad(s, {-2, 0, -2}, {-2, 0, 2}, {2, 0, 2}, {2, 0, -2}, grey);
    addQuad(s, {-2, 0, -2}, {2, 0, -2}, {2, 2, -2}, {-2, 2, -2}, red);
    addBox(s, {-0.4f, 0.0f, -0.8f}, {0.4f, 0.7f, -0.2f}, /*inward=*/false, grey);
    baked = Baked::make(std::move(s), smallOptions());
    if (!baked) return;
    Relighter r = baked->relighter();
    const surfels::Surfels& surfels = baked->p.surfels;
    std::vector<glm::vec3> unshadowed(surfels.size());
    LightSet lights;
    LightEntry lamp;
    lamp.id = "lamp";
    lamp.light.kind = scene::Light::Kind::kPoint;
    lamp.light.intensity = 10.0f;
    EXPECT_TRUE(lights.add(lamp));
    RelightResult res;
    for (int t = 0; t <= 2 * kSteps; ++t) {
      lamp.light.position = glm::vec3(-0.125f + 0.25f * float(t) / float(2 * kSteps), 1.4f, 0.6f);
      EXPECT_TRUE(lights.modify(lamp));
      Status st = r.relightInto(lights, RelightOptions{.surfel_shadow_rays = rays}, res);
      EXPECT_TRUE(st) << st.toString();
      if (!st) return;
      bench::appendFlickerFrame(res, baked->p, direct, indirect);
      for (std::size_t k = 0; k < surfels.size(); ++k)
        unshadowed[k] = scene::irradianceFrom(lamp.light, surfels.position[k], surfels.normal[k]);
      st = r.relightInto(lights, RelightOptions{.surfel_irradiance = unshadowed}, res);
      EXPECT_TRUE(st) << st.toString();
      if (!st) return;
      bench::appendFlickerFrame(res, baked->p, smooth_direct, smooth_indirect);
    }
  }
};

const LightPath& lightPath() {
  static LightPath p;
  return p;
}

TEST(Flicker, SmoothSurfelLightGivesSmoothLightmapsWhateverTheCuts) {
  // Neighbouring caches link different cuts of the hierarchy (finest next to a surface, the
  // block hides some nodes from some caches): with surfel light smooth in the light's
  // position, the pull, the links, the bounces and the fill keep the indirect smooth.
  const LightPath& path = lightPath();
  ASSERT_TRUE(path.baked);
  ASSERT_EQ(path.smooth_indirect.frames(), std::size_t(2 * LightPath::kSteps + 1));
  const auto indirect = measureFlicker(path.smooth_indirect);
  EXPECT_GT(indirect.lit_texels, path.smooth_indirect.texels / 4);
  EXPECT_LT(indirect.ratio, 0.7) << "R(s) " << indirect.coarse.roughness << " R(s/2) " << indirect.fine.roughness;
  EXPECT_EQ(indirect.popping_texels, 0u);
  // The direct light's one shadow ray per texel flips where the block's hard shadow edge
  // sweeps: those texels jump between lit and dark, as a hard shadow does. The rest is smooth.
  const auto direct = measureFlicker(path.smooth_direct);
  EXPECT_GT(direct.lit_texels, path.smooth_direct.texels / 4);
  EXPECT_LT(direct.ratio_smooth, 0.7) << direct.popping_texels << " texels pop";
  EXPECT_GT(direct.popping_texels, 0u);
  EXPECT_LT(direct.popping_texels, direct.lit_texels / 8);
  const caches::LightmapCaches& lm = path.baked->p.lightmap;
  for (std::size_t texel : direct.popping) {
    // A texel whose cache is invalid holds its neighbours' light (the fill): it jumps with them.
    if (!lm.valid[std::size_t(lm.cache_of_texel[texel])]) continue;
    float lo = INFINITY, hi = 0.0f;
    for (std::size_t t = 0; t < path.smooth_direct.frames(); ++t) {
      lo = std::min(lo, path.smooth_direct.at(t, texel));
      hi = std::max(hi, path.smooth_direct.at(t, texel));
    }
    EXPECT_EQ(lo, 0.0f) << "texel " << texel << " pops but is never in the block's shadow";
    EXPECT_GT(hi, 0.0f) << "texel " << texel;
  }
}

TEST(Flicker, FootprintShadowRaysKeepTheIndirectFromPopping) {
  // docs/quality.md, "Temporal stability": a surfel lit through one shadow ray from its centre
  // switches between lit and dark at once as the block's shadow edge sweeps the floor, and
  // caches close to it (at the block's and the wall's foot, linked to fine nodes holding few
  // surfels) jump. Surfels near a shadow edge test their footprint instead (the default
  // surfel_shadow_rays), and their light fades as the edge crosses them. The direct layer is
  // the same either way.
  const LightPath& path = lightPath();
  ASSERT_TRUE(path.baked);
  const LightPath centre(1);
  ASSERT_TRUE(centre.baked);
  const auto soft = measureFlicker(path.indirect), hard = measureFlicker(centre.indirect);
  std::printf("indirect: ratio %.3f, %zu of %zu texels pop; one ray per surfel: ratio %.3f, %zu pop\n", soft.ratio,
              soft.popping_texels, soft.lit_texels, hard.ratio, hard.popping_texels);
  EXPECT_GT(hard.popping_texels, hard.lit_texels / 5);
  EXPECT_LT(soft.popping_texels, soft.lit_texels / 50);
  EXPECT_LT(soft.popping_texels * 10, hard.popping_texels);
  EXPECT_LT(soft.ratio, 0.95);
  EXPECT_EQ(path.direct.values, path.smooth_direct.values);
  EXPECT_EQ(centre.direct.values, path.direct.values);
}

TEST(Flicker, AJumpInTheRelitSequenceIsDetected) {
  const LightPath& path = lightPath();
  ASSERT_TRUE(path.baked);
  for (const FlickerFrames* frames : {&path.smooth_indirect, &path.smooth_direct}) {
    const auto smooth = measureFlicker(*frames);
    const auto jumped = measureFlicker(withJump(*frames, 0.05f));
    EXPECT_GT(jumped.ratio, 0.9) << "without the jump " << smooth.ratio;
    EXPECT_GT(jumped.popping_texels, jumped.lit_texels / 2);
  }
}

}  // namespace
}  // namespace lightlink::relight
