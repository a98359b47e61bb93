// Bridges from received Textures to lightlink's own types, for clients that reuse core code:
// `lightlink pull` writes files with core/output's writers (which take a RelightResult and
// the caches), the example game client renders with clients/viewer (BakedLighting).
// Kept out of lightlink_client so that an engine linking the client library does not pull
// in core (Embree, TBB, OpenEXR).
#pragma once

#include "clients/client/textures.h"
#include "clients/viewer/baked_lighting.h"
#include "core/caches/caches.h"
#include "core/relight/relight.h"

namespace lightlink::client {

// The textures as a RelightResult (version, backend, bands, lightmap SH, direct, validity,
// grid SH). Payloads that were not sent stay empty / zero.
Expected<relight::RelightResult> toRelightResult(const Textures& t);

// The grid's geometry (origin, uniform spacing, dims, point positions, validity), what
// output::writeGrid* need. Fails when the textures carry no grid or its spacing is not
// uniform.
Expected<caches::GridCaches> gridCachesOf(const Textures& t);

// Lightmap "caches" for output::writeIrradiancePng. The wire carries no surface normals, so
// each valid texel's normal is the direction of its SH's linear band (luminance-weighted):
// the dominant direction of incoming light, which for a lightmap texel (light from its
// hemisphere only) lies close to the normal. Good for a preview, not for measurements.
caches::LightmapCaches previewCachesOf(const Textures& t);

// What the viewer renders with. Needs the lightmap (SH and validity); direct and grid when
// present.
Expected<viewer::BakedLighting> toBakedLighting(const Textures& t);

}  // namespace lightlink::client
