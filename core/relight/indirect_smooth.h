// IndirectSmooth (internal to core/relight): an optional 3x3 texel filter of the lightmap's
// indirect SH that removes the texel-to-texel jumps a small, brightly lit patch causes.
//
// A cache's link to a tree node carries the node's visibility as a count of link rays; a
// narrow spot light that lights a few surfels puts all of a receiver's light into the few
// rays that hit them, so neighbouring texels (different rays, different cuts: seed 000
// Fig. 7b) disagree by the rays' Poisson noise, +-40 % at 1024 rays. The filter replaces each
// texel that holds its own cache by the mean over the texels of its 3x3 neighbourhood that lie
// on its plane (same mesh and chart: gutters separate charts) and whose mirror image about it
// does too: a symmetric stencil, so a linear trend passes unchanged at chart borders and
// contact lines (a one-sided mean would pull a darkened edge towards the interior), and its
// weights are positive (no overshoot). The weights depend only on the atlas, so they are
// built once; applying them is one gather per texel, deterministic for any thread count.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "core/caches/caches.h"

namespace lightlink::relight::detail {

class IndirectSmooth {
 public:
  IndirectSmooth() = default;
  // Over the texels of `lm` whose cache has a value (`has_value`, per cache).
  static IndirectSmooth build(const caches::LightmapCaches& lm, const std::vector<std::uint8_t>& has_value);

  bool empty() const { return target_.empty(); }
  // Filters the targets' `stride` floats per texel of `data` (width * height texels), reading
  // the unfiltered values from `scratch` (a copy it makes, capacity kept).
  void apply(float* data, std::size_t stride, std::vector<float>& scratch) const;

 private:
  std::vector<std::uint32_t> target_;  // texels
  std::vector<std::uint32_t> begin_;   // targets + 1
  std::vector<std::uint32_t> source_;  // texels
  std::vector<float> weight_;
  std::size_t texels_ = 0;
};

}  // namespace lightlink::relight::detail
