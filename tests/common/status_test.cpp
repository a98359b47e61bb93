#include <gtest/gtest.h>

#include "core/common/aabb.h"
#include "core/common/status.h"

namespace lightlink {
namespace {

Expected<int> parsePositive(int v) {
  if (v <= 0) return invalidInput("value {} must be > 0", v);
  return v;
}

TEST(Status, ExpectedCarriesValueOrError) {
  auto good = parsePositive(3);
  ASSERT_TRUE(good.hasValue());
  EXPECT_EQ(*good, 3);
  auto bad = parsePositive(-2);
  ASSERT_FALSE(bad.hasValue());
  EXPECT_EQ(bad.status().code(), Code::kInvalidInput);
  EXPECT_EQ(bad.status().message(), "value -2 must be > 0");
  EXPECT_EQ(bad.status().toString(), "invalid input: value -2 must be > 0");
}

TEST(Aabb, GrowAndMeasure) {
  Aabb box;
  EXPECT_TRUE(box.empty());
  EXPECT_EQ(box.diagonal(), 0.0f);
  box.grow(glm::vec3(0, 0, 0));
  box.grow(glm::vec3(3, 4, 0));
  EXPECT_FALSE(box.empty());
  EXPECT_FLOAT_EQ(box.diagonal(), 5.0f);
  EXPECT_EQ(box.center(), glm::vec3(1.5f, 2.0f, 0.0f));
}

}  // namespace
}  // namespace lightlink
