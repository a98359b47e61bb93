// The samples' radix sort against std::sort, and its seen marks against the samples, at
// every pass count it has (one pass up to 11 surfel bits, two up to 22, three beyond).
#include "core/links/sample_sort.h"

#include <algorithm>
#include <random>
#include <vector>

#include <gtest/gtest.h>

namespace lightlink::links {
namespace {

TEST(SampleSort, SortsBySurfelThenRayAndMarksTheSeenSurfels) {
  std::mt19937 rng(5);
  for (const std::uint32_t surfel_bits : {1u, 4u, 11u, 12u, 15u, 17u, 22u, 23u}) {
    const std::uint32_t surfels = (1u << surfel_bits) - rng() % (1u << (surfel_bits - 1));
    for (const std::size_t n : {std::size_t(0), std::size_t(1), std::size_t(2), std::size_t(7), std::size_t(849),
                                std::size_t(4000)}) {
      // Ray order, as hit credit appends them; runs of neighbouring surfels, as hits fall.
      std::vector<Sample> keys, buffer(n);
      std::uint32_t ray = 0;
      while (keys.size() < n) {
        const std::uint32_t centre = rng() % surfels, run = 1 + rng() % 9;
        for (std::uint32_t k = 0; k < run && keys.size() < n; ++k)
          keys.push_back(makeSample(std::min<std::uint32_t>(surfels - 1, centre + rng() % 5), ray += 1 + rng() % 3));
      }
      std::vector<Sample> want = keys;
      std::sort(want.begin(), want.end());
      std::vector<std::uint8_t> seen(surfels, 0), want_seen(surfels, 0);
      for (const Sample k : keys) want_seen[surfelOf(k)] = 1;
      const Sample* sorted = sortSamples(keys.data(), buffer.data(), n, surfel_bits, seen.data());
      ASSERT_TRUE(std::equal(want.begin(), want.end(), sorted)) << surfel_bits << " bits, " << n << " samples";
      EXPECT_EQ(seen, want_seen) << surfel_bits << " bits, " << n << " samples";
    }
  }
}

}  // namespace
}  // namespace lightlink::links
