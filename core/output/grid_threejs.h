// The irradiance grid in the layout three.js's LightProbeGrid (WebGPU) and
// LightProbeGridWebGL (examples/jsm/lighting/, r187) sample, so a web page lights dynamic
// objects from a bake by handing three.js a Data3DTexture (docs/outputs.md, "three.js grid").
//
// three.js stores L2 SH of radiance in lightlink's order and normalisation (docs/sh.md:
// real orthonormal, no Condon-Shortley phase, band 1 = y, z, x; its shader and
// SphericalHarmonics3.getIrradianceAt apply the same clamped-cosine factors), so the
// coefficients are copied, not converted. Its texture is RGBA, nx x ny x 7 (nz + 2): the 27
// floats of a probe (c0.rgb, c1.rgb, ... c8.rgb, then one 0) packed four per texel into 7
// sub-volumes stacked along z, each with one padding slice at both ends copying its first
// and last data slice. Grids of fewer bands leave the missing coefficients 0; band 3 is
// dropped (its irradiance factor is 0). three.js puts each probe at the centre of its cell,
// so the volume is lightlink's grid grown by half a spacing on every side.
#pragma once

#include <string>
#include <vector>

#include <glm/glm.hpp>

#include "core/caches/caches.h"
#include "core/common/status.h"
#include "core/relight/relight.h"

namespace lightlink::output {

struct ThreeJsGrid {
  glm::ivec3 resolution{0};      // probes per axis (LightProbeGrid's widthProbes, ...)
  glm::vec3 min{0.0f}, max{0.0f};  // the volume: boundingBox, in metres
  int depth = 0;                 // texture depth, 7 * (resolution.z + 2)
  std::vector<float> rgba;       // width x height x depth texels, x fastest, 4 floats each
};

Expected<ThreeJsGrid> threeJsGrid(const relight::RelightResult& result, const caches::GridCaches& grid);

// Writes `json_path` (volume, resolution, texture size and type, the data file's name) and
// the texture as little-endian float32 next to it, named `bin_name`.
Status writeThreeJsGrid(const relight::RelightResult& result, const caches::GridCaches& grid,
                        const std::string& json_path, const std::string& bin_name);

}  // namespace lightlink::output
