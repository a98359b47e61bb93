// StaticSurface: the static triangles of a scene as one flat, adjacency-aware list.
//
// Surfel placement walks the triangles in order of their cumulative area, and relaxation
// moves points across shared edges; both want every static triangle as a flat record (corner,
// edges, unit normal) and, per edge, the triangle on the other side. Triangles are numbered
// globally over the static meshes in scene order ("surface triangle" ids), each remembering
// its (mesh, triangle). Edges are matched by vertex *positions* (bit-exact), not indices, so
// the vertex splits glTF exporters make at UV seams and hard normals do not cut the surface;
// an edge shared by more than two triangles (non-manifold) has no neighbour.
//
// A double-sided surface (glTF `doubleSided`) is two surfaces: after all front triangles, each
// static triangle of a double-sided material appears once more as its *back* copy (same
// corner and edges, so the same barycentrics; normal negated; neighbours are the back copies
// of its front neighbours). Surfels placed on a back copy stand for the back side, so light
// reflected by one side of a sheet never leaves from the other.
//
// Points on a triangle use Embree's barycentrics: p = (1-u-v) p0 + u p1 + v p2.
#pragma once

#include <cstdint>
#include <vector>

#include <glm/glm.hpp>

#include "core/common/status.h"
#include "core/scene/scene.h"

namespace lightlink::surfels {

struct StaticSurface {
  std::vector<std::uint32_t> mesh;      // index into Scene::meshes
  std::vector<std::uint32_t> triangle;  // triangle within that mesh
  std::vector<glm::vec3> p0, e1, e2;    // corner 0 and edges p1 - p0, p2 - p0 (world, metres)
  std::vector<glm::vec3> normal;        // unit geometric normal (e1 x e2, negated on a back copy), (0,0,0) if degenerate
  std::vector<std::uint8_t> back;       // 1: the back copy of a double-sided triangle
  std::vector<double> area_prefix;      // size()+1 entries: sum of areas (m^2) of triangles < t
  // 3 per triangle: the surface triangle across the edge opposite corner k, or -1.
  std::vector<std::int32_t> neighbour;

  std::size_t size() const { return mesh.size(); }
  double totalArea() const { return area_prefix.back(); }
  glm::vec3 pointAt(std::uint32_t t, glm::vec2 uv) const { return p0[t] + uv.x * e1[t] + uv.y * e2[t]; }
};

// Rejects non-finite positions and out-of-range indices (invalid input naming the mesh).
Expected<StaticSurface> buildStaticSurface(const scene::Scene& scene);

// Moves the point (t, uv) by the world displacement `delta_m`, keeping it on the surface:
// the part of `delta_m` along the triangle normal is dropped, and where the path leaves the
// triangle it continues into the neighbour across that edge if the two are coplanar within
// `cos_coplanar`; otherwise it stops on the edge. At most `max_crossings` edges are crossed.
void moveOnSurface(const StaticSurface& surface, std::uint32_t& t, glm::vec2& uv, glm::vec3 delta_m,
                   float cos_coplanar, int max_crossings = 8);

// Barycentrics of the projection of `p` onto the plane of t, clamped into the triangle.
glm::vec2 clampedBarycentric(const StaticSurface& surface, std::uint32_t t, const glm::vec3& p);

}  // namespace lightlink::surfels
