// Warm start (RelightOptions::warm_start): the bounce iteration starts from the last relight's
// solution, so after a light move one iteration comes close to the converged answer and
// further warm relights of the same light set converge to what a cold relight gives.
#include <cmath>
#include <cstdio>

#include <gtest/gtest.h>

#include "tests/relight/relight_fixture.h"

namespace lightlink::relight {
namespace {

using namespace lightlink::relight::testing;
using lightlink::testing::addBox;

// A bright room (albedo 0.8) where bounces carry much of the light, with a grid.
std::unique_ptr<Baked> brightRoom() {
  scene::Scene s;
  const int m = addMaterial(s, glm::vec3(0.8f, 0.75f, 0.7f));
  addBox(s, {0, 0, 0}, {6, 2, 2}, /*inward=*/true, m);
  addBox(s, {2.5f, 0, 0.6f}, {3.5f, 1.2f, 1.4f}, /*inward=*/false, m);  // a pillar between the ends
  auto o = smallOptions();
  o.grid = precompute::GridMode::kOn;
  o.grid_resolution = 4;
  return Baked::make(std::move(s), o);
}

LightSet lampAt(glm::vec3 pos) {
  LightSet set;
  LightEntry e;
  e.id = "lamp";
  e.light.kind = scene::Light::Kind::kPoint;
  e.light.position = pos;
  e.light.intensity = 5.0f;
  EXPECT_TRUE(set.add(e));
  return set;
}

// Relative L2 distance of two results' indirect SH.
double distance(const RelightResult& a, const RelightResult& b) {
  EXPECT_EQ(a.lightmap_sh.size(), b.lightmap_sh.size());
  double d = 0.0, n = 0.0;
  for (std::size_t i = 0; i < a.lightmap_sh.size(); ++i) {
    const double x = double(a.lightmap_sh[i]) - b.lightmap_sh[i];
    d += x * x, n += double(b.lightmap_sh[i]) * b.lightmap_sh[i];
  }
  return std::sqrt(d / std::max(n, 1e-30));
}

const RelightOptions kConverged{.max_bounces = 200, .bounce_threshold = 1e-5f};
const RelightOptions kOneWarm{.max_bounces = 1, .bounce_threshold = 0.0f, .warm_start = true};

TEST(WarmStart, OneIterationAfterAMoveIsCloseAndMoreConverge) {
  auto baked = brightRoom();
  ASSERT_TRUE(baked);
  const LightSet a = lampAt({1.0f, 1.5f, 1.0f}), b = lampAt({1.6f, 1.5f, 1.0f});
  auto target = baked->relighter().relight(b, kConverged);
  ASSERT_TRUE(target);
  ASSERT_EQ(target->bounce_stop, "threshold");
  auto cold_one = baked->relighter().relight(b, {.max_bounces = 1, .bounce_threshold = 0.0f});
  ASSERT_TRUE(cold_one);

  Relighter r = baked->relighter();
  ASSERT_TRUE(r.relight(a, kConverged));
  auto warm = r.relight(b, kOneWarm);
  ASSERT_TRUE(warm) << warm.status().toString();
  EXPECT_EQ(warm->passes.warm, 1);
  EXPECT_EQ(warm->passes.bounces, 1);
  const double warm_error = distance(*warm, *target), cold_error = distance(*cold_one, *target);
  // The higher bounces come from the last solution: far closer than one cold bounce.
  EXPECT_LT(warm_error, 0.25 * cold_error) << "warm " << warm_error << ", cold " << cold_error;
  // The figure docs/relight.md and docs/service.md quote.
  std::printf("one warm iteration: %.3f from the converged answer; one cold bounce: %.3f\n", warm_error, cold_error);

  // Each further warm relight of the same set is one more iteration: the change it reports
  // shrinks, and the result converges to the cold answer.
  double last_change = 1.0;
  for (int k = 0; k < 60 && last_change > 1e-5; ++k) {
    auto more = r.relight(b, kOneWarm);
    ASSERT_TRUE(more);
    ASSERT_EQ(more->passes.warm, 1);
    ASSERT_EQ(more->passes.unchanged, 0);
    ASSERT_EQ(more->bounce_log.size(), 1u);
    const double change = more->bounce_log[0].added_flux / more->bounce_log[0].total_flux;
    EXPECT_LE(change, last_change * 1.0001) << "iteration " << k;
    last_change = change;
    if (change <= 1e-5) {
      EXPECT_LT(distance(*more, *target), 1e-3);
      EXPECT_LT(distance(*more, *target), 0.05 * warm_error);
    }
  }
  EXPECT_LE(last_change, 1e-5);
}

TEST(WarmStart, WithoutAKeptSolutionItIsACold) {
  auto baked = brightRoom();
  ASSERT_TRUE(baked);
  const LightSet b = lampAt({1.6f, 1.5f, 1.0f});
  const RelightOptions warm_opt{.max_bounces = 3, .bounce_threshold = 0.0f, .warm_start = true};
  const RelightOptions cold_opt{.max_bounces = 3, .bounce_threshold = 0.0f};
  Relighter r = baked->relighter();
  auto first = r.relight(b, warm_opt);
  auto cold = baked->relighter().relight(b, cold_opt);
  ASSERT_TRUE(first && cold);
  EXPECT_EQ(first->passes.warm, 0);
  EXPECT_EQ(first->lightmap_sh, cold->lightmap_sh);
  // Another band count is no base either.
  RelightOptions two_bands = warm_opt;
  two_bands.bands = 2;
  auto other = r.relight(b, two_bands);
  ASSERT_TRUE(other);
  EXPECT_EQ(other->passes.warm, 0);
  r.invalidate();
  auto after = r.relight(b, warm_opt);
  ASSERT_TRUE(after);
  EXPECT_EQ(after->passes.warm, 0);
}

TEST(WarmStart, AColdRelightAfterAWarmOneIsNotTakenFromIt) {
  auto baked = brightRoom();
  ASSERT_TRUE(baked);
  const LightSet a = lampAt({1.0f, 1.5f, 1.0f}), b = lampAt({1.6f, 1.5f, 1.0f});
  Relighter r = baked->relighter();
  ASSERT_TRUE(r.relight(a, kConverged));
  ASSERT_TRUE(r.relight(b, kOneWarm));
  auto cold = r.relight(b, {.max_bounces = 1, .bounce_threshold = 0.0f});
  auto fresh = baked->relighter().relight(b, {.max_bounces = 1, .bounce_threshold = 0.0f});
  ASSERT_TRUE(cold && fresh);
  EXPECT_EQ(cold->passes.unchanged, 0);
  EXPECT_EQ(cold->passes.warm, 0);
  EXPECT_EQ(cold->lightmap_sh, fresh->lightmap_sh);
}

}  // namespace
}  // namespace lightlink::relight
