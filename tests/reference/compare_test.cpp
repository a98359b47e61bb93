#include "core/reference/compare.h"

#include <cmath>
#include <vector>

#include <gtest/gtest.h>

namespace lightlink::reference {
namespace {

TEST(ErrorStats, KnownErrorsGiveKnownFigures) {
  // Grey values so luminance = value. Errors: +10 %, -10 %, 0, 0 (and one black reference).
  const std::vector<glm::vec3> ref = {glm::vec3(1), glm::vec3(2), glm::vec3(4), glm::vec3(8), glm::vec3(0)};
  const std::vector<glm::vec3> baked = {glm::vec3(1.1f), glm::vec3(1.8f), glm::vec3(4), glm::vec3(8), glm::vec3(0.5f)};
  const ErrorStats s = errorStats(baked, ref);
  EXPECT_EQ(s.points, 5u);
  EXPECT_EQ(s.black_points, 1u);
  EXPECT_NEAR(s.rel_rmse, std::sqrt((0.01 + 0.01) / 4.0), 1e-6);
  EXPECT_NEAR(s.max_rel_error, 0.1, 1e-6);
  EXPECT_NEAR(s.p95_rel_error, 0.1, 1e-6);
  EXPECT_NEAR(s.bias, (1.1 + 1.8 + 4 + 8 + 0.5) / 15.0, 1e-6);
}

TEST(ErrorStats, PerfectMatchAndEmptyInput) {
  const std::vector<glm::vec3> v = {glm::vec3(0.5f, 1.0f, 2.0f), glm::vec3(3.0f)};
  const ErrorStats s = errorStats(v, v);
  EXPECT_EQ(s.rel_rmse, 0.0);
  EXPECT_EQ(s.bias, 1.0);
  EXPECT_EQ(errorStats({}, {}).points, 0u);
}

}  // namespace
}  // namespace lightlink::reference
