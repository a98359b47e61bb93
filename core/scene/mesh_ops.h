// Geometry clean-up on a MeshInstance shared by the ingest and by anyone who edits a
// Scene afterwards (e.g. a subdivision for benchmarks): area-weighted vertex normals and
// the removal of degenerate triangles. Works in world space, metres.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include <glm/glm.hpp>

#include "core/scene/scene.h"

namespace lightlink::scene {

// Area-weighted vertex normals of `indices` (3 per triangle, counter-clockwise = front).
// A vertex no triangle with area touches gets +Z so every normal is unit length.
void generateVertexNormals(const std::vector<glm::vec3>& positions,
                           const std::vector<std::uint32_t>& indices,
                           std::vector<glm::vec3>& normals);

// Turns `mesh.normals`, given in mesh space (or empty), into world-space unit normals: the
// inverse transpose of `linear` (the mesh-to-world linear part), renormalised. Normals that
// come out zero-length or non-finite, or all of them when there are none, are taken from
// generateVertexNormals over the (world-space) positions and indices; an empty input sets
// `normals_generated`. Returns how many given normals were replaced.
std::size_t worldNormalsOrGenerated(const glm::dmat3& linear, MeshInstance& mesh);

// Triangle area in m^2, computed in double so large coordinates do not cancel.
double triangleArea(const glm::vec3& a, const glm::vec3& b, const glm::vec3& c);

// Removes triangles with a repeated index or an area below `min_area_m2`, keeping the
// order of the rest; vertices are left untouched (they stay 1:1 with the glTF accessor).
// Returns how many triangles were removed.
std::size_t dropDegenerateTriangles(MeshInstance& mesh, double min_area_m2);

}  // namespace lightlink::scene
