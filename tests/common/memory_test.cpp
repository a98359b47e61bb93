#include "core/common/memory.h"

#include <cstdint>
#include <vector>

#include <gtest/gtest.h>

namespace lightlink {
namespace {

// The hint changes no contents and no capacity rule: a vector reserved "huge" fills and
// reads back like any other, at sizes below, at and past a 2 MiB page.
TEST(Memory, ReserveHugeKeepsTheVectorsContract) {
  for (const std::size_t n : {std::size_t(0), std::size_t(1000), std::size_t(1) << 19, (std::size_t(3) << 20) + 7}) {
    std::vector<std::uint32_t> v = {7, 8, 9};
    reserveHuge(v, n);
    EXPECT_GE(v.capacity(), n);
    ASSERT_EQ(v.size(), 3u);
    EXPECT_EQ(v[0], 7u);
    EXPECT_EQ(v[2], 9u);
    const std::uint32_t* before = v.data();
    for (std::size_t i = 3; i < n; ++i) v.push_back(static_cast<std::uint32_t>(i * 2654435761u));
    if (n > 3) {
      EXPECT_EQ(v.data(), before) << "filling within the reserve must not reallocate";
    }
    for (std::size_t i = 3; i < n; ++i) ASSERT_EQ(v[i], static_cast<std::uint32_t>(i * 2654435761u));
  }
}

TEST(Memory, AdviceOnAnyRangeIsHarmless) {
  std::vector<char> small(100, 'x');
  adviseHugePages(small.data(), small.size());  // nothing inside it is a whole 2 MiB page
  adviseHugePages(nullptr, 0);
  EXPECT_EQ(small[99], 'x');
}

}  // namespace
}  // namespace lightlink
