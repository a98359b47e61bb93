// The SIMD tier switch (core/common/isa.h): names, the limit, and that the active tier never
// exceeds what the CPU runs.
#include <gtest/gtest.h>

#include "core/common/isa.h"

namespace lightlink {
namespace {

TEST(Isa, NamesParseAndGarbageIsRejectedByName) {
  for (Isa t : {Isa::kBaseline, Isa::kAvx2, Isa::kAvx512}) {
    auto p = parseIsa(isaName(t));
    ASSERT_TRUE(p);
    EXPECT_EQ(*p, t);
  }
  auto bad = parseIsa("sse9");
  ASSERT_FALSE(bad);
  EXPECT_NE(bad.status().message().find("'sse9'"), std::string::npos) << bad.status().message();
}

TEST(Isa, TheLimitLowersTheActiveTierAndNeverRaisesIt) {
  setIsaLimit(Isa::kBaseline);
  EXPECT_EQ(activeIsa(), Isa::kBaseline);
  EXPECT_FALSE(isaAtLeast(Isa::kAvx2));
  setIsaLimit(Isa::kAvx512);
  EXPECT_EQ(activeIsa(), cpuIsa());
  setIsaLimit(Isa::kAvx2);
  EXPECT_LE(int(activeIsa()), int(Isa::kAvx2));
  EXPECT_LE(int(activeIsa()), int(cpuIsa()));
  setIsaLimit(Isa::kAvx512);
}

}  // namespace
}  // namespace lightlink
