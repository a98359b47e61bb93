// The precompute tests' scene and options: the bundled Cornell box (it has a dynamic probe,
// so lightmap and grid caches both exist) at a size that precomputes in well under a second.
#pragma once

#include <string>

#include "core/precompute/precompute.h"
#include "tests/common/testing.h"

namespace lightlink::precompute {

inline const std::string kDemo = (testing::sourceDir() / "clients/demo/cornell_box.gltf").string();

inline PrecomputeOptions smallOptions() {
  PrecomputeOptions o;
  o.surfels = 1024;
  o.links = 32;
  o.rays = 256;
  o.target_resolution = 32;
  o.grid_resolution = 6;
  o.validity_rays = 16;
  return o;
}

}  // namespace lightlink::precompute
