// The sort of link generation's samples: a cache's credited hits, appended in ray order,
// sorted by surfel (tree order) so that every tree node's hits are one run of samples for
// the cut. A radix sort on the surfel bits alone (stable, so rays stay in order within a
// surfel), whose first pass also marks the surfels seen (it reads every sample anyway).
#pragma once

#include <cstddef>
#include <cstdint>

#include "core/links/cut.h"

namespace lightlink::links {

// Sorts n samples, given in ray order with surfels below 2^surfel_bits (surfel_bits >= 1),
// by (surfel, ray). `keys` and `buffer` hold n samples each; returns the one that holds the
// result. seen[surfel] is set to 1 for every sample's surfel.
Sample* sortSamples(Sample* keys, Sample* buffer, std::size_t n, std::uint32_t surfel_bits, std::uint8_t* seen);

}  // namespace lightlink::links
