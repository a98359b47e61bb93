// The near-contact band of a lightmap (docs/quality.md): texels whose surface point lies within
// a given distance (two texel sizes in `compare`) of another surface, i.e. where a wall meets a
// floor, a prop stands on the ground or a rug lies on it. That is where bakers leak and where
// the interior error hides the band's error, so `compare` reports the band on its own.
//
// A point is in the band when any of a fixed fan of short rays leaving its surface into the
// hemisphere of its normal (elevations 5, 30, 60 and 90 degrees, 8 azimuths each) hits geometry
// within the radius. Rays that leave the surface never find coplanar neighbours (the other
// triangles of the same flat wall), so only surfaces at an angle, or parallel ones above the
// point, count. Deterministic: the fan is fixed.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include <glm/glm.hpp>

#include "core/rt/accel.h"
#include "core/scene/scene.h"

namespace lightlink::reference {

// 1 where the point (position, unit normal) has another surface within radius[i] metres.
std::vector<std::uint8_t> nearContact(const rt::Accel& accel, std::span<const glm::vec3> positions,
                                      std::span<const glm::vec3> normals, std::span<const float> radius);

// Metres of surface per lightmap texel on one triangle of a mesh with a lightmap UV (uv1), for
// an atlas of width x height texels: sqrt(world area / area in texels). 0 without uv1.
float texelSizeOnTriangle(const scene::MeshInstance& mesh, std::uint32_t triangle, int width, int height);

}  // namespace lightlink::reference
