// An independent, slow check of a lightmap atlas for the tests: brute-force texel-square
// vs triangle tests (separating axes) over a full-resolution buffer, written separately
// from core/charts/rasterize so the two cannot share a bug.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "core/charts/unwrap.h"
#include "core/scene/scene.h"

namespace lightlink::charts::testing {

struct OracleResult {
  std::size_t chart_overlap_texels = 0;  // texels touched (closed squares) by two charts
  std::size_t center_overlaps = 0;       // texel centres strictly inside two triangles
  std::size_t gutter_violations = 0;     // texel pairs of different charts within the gutter
  std::size_t flipped = 0;               // uv1 triangles with area <= 0
  std::size_t out_of_range = 0;          // uv1 values outside [0, 1]
  std::size_t covered = 0;
  std::string first_problem;             // human-readable description of the first failure
};

OracleResult checkWithOracle(const scene::Scene& scene, const LightmapAtlas& atlas);

}  // namespace lightlink::charts::testing
