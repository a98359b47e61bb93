// Material evaluation at a point on a triangle, for surfels, the reference path tracer
// and anyone else who needs what a surface reflects or emits there.
//
// A point is named by (mesh, triangle, barycentric) with Embree's convention:
// p = (1 - u - v) * p0 + u * p1 + v * p2 for barycentric = (u, v) and the triangle's
// corners p0, p1, p2 in index order. Textures are sampled at the texture reference's own
// TEXCOORD set; a reference to a set the mesh lacks falls back to the factor alone.
#pragma once

#include <cstdint>

#include <glm/glm.hpp>

#include "core/scene/scene.h"

namespace lightlink::scene {

// Interpolated TEXCOORD_`set` (0 or 1); (0, 0) when the mesh has no such set.
glm::vec2 texcoordAt(const MeshInstance& mesh, int set, std::uint32_t triangle,
                     glm::vec2 barycentric);

// Diffuse albedo, linear RGB: baseColorFactor.rgb * baseColorTexture.rgb (sRGB decoded).
glm::vec3 albedoAt(const Scene& scene, const MeshInstance& mesh, std::uint32_t triangle,
                   glm::vec2 barycentric);

// Emitted radiance, linear RGB in the units of docs/units.md:
// emissiveFactor * KHR_materials_emissive_strength * emissiveTexture.rgb (sRGB decoded).
glm::vec3 emissionAt(const Scene& scene, const MeshInstance& mesh, std::uint32_t triangle,
                     glm::vec2 barycentric);

// Base-colour alpha: baseColorFactor.a * baseColorTexture.a (linear), and whether the point
// is cut out: the material is MASK or BLEND and the alpha is below its threshold (the test
// the ray tracer applies to every hit, core/rt/cutout.h).
// Albedo for light transport: albedoAt, or 0 for a mesh that contributes no GI
// (MeshInstance::contribute_gi), so it reflects no bounce light. Display uses albedoAt.
glm::vec3 bounceAlbedoAt(const Scene& scene, const MeshInstance& mesh, std::uint32_t triangle, glm::vec2 barycentric);

float alphaAt(const Scene& scene, const MeshInstance& mesh, std::uint32_t triangle, glm::vec2 barycentric);
bool cutOutAt(const Scene& scene, const MeshInstance& mesh, std::uint32_t triangle, glm::vec2 barycentric);

}  // namespace lightlink::scene
