// Encodings an engine picks (docs/outputs.md "Encodings"): how much of a relight's SH the
// written lightmap and grid keep, and the one evaluation of the surface's irradiance that
// the L0 map (irradiance.exr), the PNG preview and the encoding figures share.
//
//   L0  the lightmap as RGB irradiance for the surface's own normal: the indirect SH of the
//       full result evaluated at the cache normal (clamped-cosine factors, never negative)
//       plus the baked direct irradiance. No SH maps; the grid keeps band 0 (L00) only, the
//       direction-averaged light, since a grid point has no surface normal.
//   L1  SH bands 0-1 (4 coefficients) of lightmap and grid: the truncation of the result's
//       SH, which for orthonormal SH is the best 4-coefficient fit.
//   L2  every band of the result (9 coefficients at 3 bands; 16 when glossy bands are on).
// irradiance.exr is written for every encoding, always from the full result.
#pragma once

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include <glm/glm.hpp>

#include "core/caches/caches.h"
#include "core/common/status.h"
#include "core/relight/relight.h"

namespace lightlink::output {

enum class Encoding { kL0, kL1, kL2 };

// "l0", "l1", "l2" (the --encoding values); anything else is rejected, naming the choices.
Expected<Encoding> parseEncoding(std::string_view name);
std::string_view encodingName(Encoding e);
// SH bands the lightmap keeps of a result with `result_bands` bands (0 for L0: no SH maps).
int lightmapBands(Encoding e, int result_bands);
// SH bands the grid keeps (at least 1: L0 keeps L00).
int gridBands(Encoding e, int result_bands);

// SH laid out per element as 3 * from_bands^2 floats (R coefficients, then G, then B), cut to
// the first to_bands bands of each channel; to_bands >= from_bands returns a copy.
std::vector<float> truncateSh(const std::vector<float>& sh, int from_bands, int to_bands);

// The surface's irradiance per texel, in the units of the result (docs/units.md).
struct IrradianceImage {
  int width = 0, height = 0;
  std::vector<glm::vec3> irradiance;  // y * width + x; 0 where no texel value
  std::vector<std::uint8_t> lit;      // 1 where the texel holds a value
};
// Indirect SH evaluated at each texel's cache normal (+ the baked direct when include_direct).
// With a finer direct layer and its texels (Precomputation::direct_texels), the image has
// the direct layer's size: the indirect SH interpolated bilinearly over valid lightmap
// texels, evaluated at the direct texel's own normal. A finer layer without its texels is
// refused when include_direct is set (its direct light has no lightmap-size form). Texels the
// relight filled by dilation (valid, without a cache) take the mean of their evaluated
// neighbours, so the gutters around charts hold light as the SH layer's do.
Expected<IrradianceImage> evaluateIrradiance(const relight::RelightResult& result,
                                             const caches::LightmapCaches& lightmap, bool include_direct = true,
                                             const caches::LightmapCaches* direct_texels = nullptr);

}  // namespace lightlink::output
