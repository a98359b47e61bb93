// Surfels: the senders of the light transport (seed 000 sec. 4.1).
//
// `placeSurfels` covers all *static* geometry with nS surfels of equal area: the static
// triangles are laid end to end by area and surfel j owns the triangle under the midpoint
// (j + 1/2) * A/nS of that line, so every triangle gets surfels in proportion to its area and
// small triangles accumulate into the surfel whose area slice they fall in. A surfel's area is
// the slice it represents (A/nS), so the areas sum to the static geometry area exactly (up to
// float rounding). Inside a triangle the surfels follow a Halton sequence (bases 2 and 3) with
// a per-triangle random start; then a few Jacobi iterations of tangential relaxation push
// each surfel away from neighbours closer than the ideal hexagonal spacing. Relaxation moves
// a surfel within its own triangle and across edges into neighbouring triangles of the same
// mesh that are coplanar within ~8 degrees; at any other edge it stops on the edge. Attributes
// (normal, albedo, emission, lightmap UV) are evaluated at the final position, textures
// included.
//
// A double-sided material's triangles are on that line twice, once per side (surface.h): each
// side gets its own surfels, with normals facing that side (a back-side surfel's normal points
// against its triangle's winding normal), so the two sides are lit, reflect and are found by
// link rays separately; nS counts both sides.
//
// Dynamic meshes (MeshInstance::is_static == false) get no surfels. A scene without static
// area gives an empty set, not an error. Results are identical for any TBB thread count.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include <glm/glm.hpp>

#include "core/common/progress.h"
#include "core/common/status.h"
#include "core/scene/scene.h"

namespace lightlink::surfels {

struct SurfelOptions {
  std::uint32_t count = 32768;     // nS: exactly this many surfels when the static area is > 0
  int relaxation_iterations = 8;   // 0 keeps the Halton positions
  // Largest move per relaxation iteration as a fraction of the ideal spacing; in (0, 1].
  float relaxation_step = 0.3f;
  std::uint32_t seed = 0;          // varies the per-triangle Halton start
  const Progress* progress = nullptr;  // polled for cancellation: placeSurfels then gives kCancelled
};

// Structure of arrays, one entry per surfel in every array.
struct Surfels {
  std::vector<glm::vec3> position;      // world space, metres, on the owning triangle
  std::vector<glm::vec3> normal;        // unit; interpolated vertex normal at the position
  std::vector<float> area;              // m^2, the area of geometry this surfel stands for
  std::vector<glm::vec3> albedo;        // linear RGB diffuse reflectance (texture sampled)
  std::vector<glm::vec3> emission;      // emitted radiance (docs/units.md), texture sampled
  std::vector<glm::vec2> lightmap_uv;   // TEXCOORD_1 at the position; (-1, -1) if the mesh has none
  std::vector<std::uint32_t> mesh;      // index into Scene::meshes
  std::vector<std::uint32_t> triangle;  // triangle index within that mesh
  std::vector<glm::vec2> barycentric;   // (u, v): p = (1-u-v) p0 + u p1 + v p2 (Embree's)

  std::size_t size() const { return position.size(); }
  bool empty() const { return position.empty(); }
  void resize(std::size_t n);
};

Expected<Surfels> placeSurfels(const scene::Scene& scene, const SurfelOptions& options);

// Permutes every array: afterwards element i is the former element new_to_old[i].
// `new_to_old` must be a permutation of [0, size()).
void reorder(Surfels& surfels, std::span<const std::uint32_t> new_to_old);

}  // namespace lightlink::surfels
