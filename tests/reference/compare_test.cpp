#include "core/reference/compare.h"

#include <cmath>
#include <vector>

#include <gtest/gtest.h>

namespace lightlink::reference {
namespace {

TEST(ErrorStats, KnownErrorsGiveKnownFigures) {
  // Grey values so luminance = value. Errors: +10 %, -10 %, 0, 0, and a black reference lit
  // at 0.5: mean reference 3, floor 0.05 * 3 = 0.15, so that point's error is 0.5 / 0.15.
  const std::vector<glm::vec3> ref = {glm::vec3(1), glm::vec3(2), glm::vec3(4), glm::vec3(8), glm::vec3(0)};
  const std::vector<glm::vec3> baked = {glm::vec3(1.1f), glm::vec3(1.8f), glm::vec3(4), glm::vec3(8), glm::vec3(0.5f)};
  const ErrorStats s = errorStats(baked, ref);
  EXPECT_EQ(s.points, 5u);
  EXPECT_EQ(s.black_points, 1u);
  const double leak = 0.5 / 0.15;
  EXPECT_NEAR(s.floor, 0.15, 1e-6);
  EXPECT_NEAR(s.rel_rmse, std::sqrt((0.01 + 0.01 + leak * leak) / 5.0), 1e-5);
  EXPECT_NEAR(s.max_rel_error, leak, 1e-5);
  EXPECT_NEAR(s.p95_rel_error, leak, 1e-5);
  EXPECT_NEAR(s.lit_rel_rmse, std::sqrt((0.01 + 0.01) / 4.0), 1e-6);  // the figure before issue 46
  EXPECT_NEAR(s.lit_p95_rel_error, 0.1, 1e-6);
  EXPECT_NEAR(s.bias, (1.1 + 1.8 + 4 + 8 + 0.5) / 15.0, 1e-6);
  EXPECT_EQ(s.leaks, 1u);
  EXPECT_EQ(s.missing_light, 0u);
}

TEST(ErrorStats, ALeakOnBlackReferenceShowsInTheHeadlineError) {
  // 1000 points 1 % off, and 10 points the reference sees black that the bake lights at the
  // scene's light level (a floor under a card lit through it). The relative error over lit
  // points alone says 1 %; the floored error must not.
  std::vector<glm::vec3> ref(1010, glm::vec3(1.0f)), baked(1010, glm::vec3(1.01f));
  for (int i = 1000; i < 1010; ++i) {
    ref[i] = glm::vec3(0.0f);
    baked[i] = glm::vec3(1.0f);
  }
  const ErrorStats s = errorStats(baked, ref);
  EXPECT_GT(s.rel_rmse, 0.5);
  EXPECT_GT(s.max_rel_error, 10.0);
  EXPECT_NEAR(s.lit_rel_rmse, 0.01, 1e-4);
  EXPECT_EQ(s.leaks, 10u);
  EXPECT_EQ(s.missing_light, 0u);
  // And the opposite: a lit point the bake leaves black.
  std::swap(ref, baked);
  EXPECT_EQ(errorStats(baked, ref).missing_light, 10u);
  EXPECT_EQ(errorStats(baked, ref).leaks, 0u);
}

TEST(ErrorStats, DarkPointsWithinTheFloorAreNotBlownUp) {
  // A corner at 0.1 % of the mean baked at 0.2 %: 100 % off by its own value, but 0.1 % of the
  // scene's light level; against the floor (5 % of the mean) it reads 2 %.
  std::vector<glm::vec3> ref(100, glm::vec3(1.0f)), baked(100, glm::vec3(1.0f));
  ref[0] = glm::vec3(1e-3f);
  baked[0] = glm::vec3(2e-3f);
  const ErrorStats s = errorStats(baked, ref);
  EXPECT_NEAR(s.max_rel_error, 1e-3 / (0.05 * (99 + 1e-3) / 100), 1e-4);
  EXPECT_EQ(s.leaks, 0u);
}

TEST(ErrorStats, ASubsetIsJudgedByTheGivenMean) {
  const std::vector<glm::vec3> ref = {glm::vec3(0.0f)}, baked = {glm::vec3(0.1f)};
  ErrorOptions o;
  o.floor_mean = 1.0;  // the whole scene's mean: floor 0.05
  const ErrorStats s = errorStats(baked, ref, o);
  EXPECT_NEAR(s.floor, 0.05, 1e-9);
  EXPECT_NEAR(s.rel_rmse, 2.0, 1e-5);
  EXPECT_EQ(s.leaks, 1u);
}

TEST(ErrorStats, PerfectMatchAndEmptyInput) {
  const std::vector<glm::vec3> v = {glm::vec3(0.5f, 1.0f, 2.0f), glm::vec3(3.0f)};
  const ErrorStats s = errorStats(v, v);
  EXPECT_EQ(s.rel_rmse, 0.0);
  EXPECT_EQ(s.lit_rel_rmse, 0.0);
  EXPECT_EQ(s.bias, 1.0);
  EXPECT_EQ(errorStats({}, {}).points, 0u);
}

}  // namespace
}  // namespace lightlink::reference
