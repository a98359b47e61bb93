// Lightmap texels over alpha cut-outs: a texel whose cache lies on a hole of a MASK
// (or BLEND) surface stands for nothing an engine will draw (it alpha-tests those pixels away),
// and every ray passes through it, so it is marked invalid and filled from its valid
// neighbours like any other invalid texel: the opaque edges of a leaf bleed outwards instead
// of the hole's unrelated value bleeding in.
#pragma once

#include <cstddef>

#include "core/caches/caches.h"
#include "core/scene/scene.h"

namespace lightlink::caches {

// Marks invalid the valid caches whose point is cut out (scene::cutOutAt at the point's
// barycentrics on its triangle); returns how many.
std::size_t invalidateCutoutTexels(const scene::Scene& scene, LightmapCaches& caches);

}  // namespace lightlink::caches
