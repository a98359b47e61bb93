// Unshadowed irradiance from one KHR_lights_punctual light, exactly as the glTF spec
// defines the light (docs/units.md):
//   point/spot: E = color * I[cd] * cos(theta) / d^2 * window(d) * spot(angle)
//     window(d) = clamp(1 - (d / range)^4, 0, 1)^2 when range > 0, else 1
//     spot = t^2, t = clamp((cos(angle) - cos(outer)) / (cos(inner) - cos(outer)), 0, 1)
//   directional: E = color * E[lux] * cos(theta)
// theta is the angle between the surface normal and the direction towards the light;
// back-facing points receive 0. Result: lux per linear colour channel.
#pragma once

#include <glm/glm.hpp>

#include "core/scene/scene.h"

namespace lightlink::scene {

// `normal` must be unit length. A point exactly at a point/spot light's position receives 0
// (the 1/d^2 singularity has no finite value; callers place caches off the light).
glm::vec3 irradianceFrom(const Light& light, glm::vec3 point, glm::vec3 normal);

// The spot factor alone (1 for point and directional lights) for a unit vector
// `light_to_point`.
float spotAttenuation(const Light& light, glm::vec3 light_to_point);

// glTF's recommended range window for a distance in metres (1 when range is 0 = infinite).
float rangeWindow(const Light& light, float distance_m);

}  // namespace lightlink::scene
