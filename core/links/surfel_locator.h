// SurfelLocator: which surfel owns a point on the static geometry.
//
// Link generation traces rays from caches and must credit each hit to the surfel that
// stands for that piece of surface. Surfels are (after relaxation) close to a Poisson-disc
// set, so the owner is the nearest surfel on the same side of the same surface: the
// nearest one whose normal agrees with the hit's shading side. A dense uniform grid over
// the surfels (cell ~2 surfel spacings, CSR layout: one offsets array, one id array) makes
// the query a scan of 27 cells of a few surfels each, with no allocation per query. The
// locator copies what it needs; the Surfels may go away after construction.
//
// Most hits are cheaper than that: the ray tracer already says which triangle was hit, and
// detailed geometry has only a few surfels per triangle. Each triangle keeps the list of
// surfels lying on it (or, when none does, the one nearest its centroid); a triangle with
// at most kTriangleListMax of them answers from that list alone (the owner is then the
// nearest surfel *on the hit triangle*, a partition of the surface as good as the nearest
// overall for lighting). A triangle with more surfels (walls of a box, floors of a level)
// bins them in a small grid over its barycentric square, and a hit scans the 3 x 3 cells
// around its own (u, v): ~20 candidates instead of the 3D grid's ~200. The 3D grid remains
// for hits without a triangle answer.
#pragma once

#include <cstdint>
#include <limits>
#include <vector>

#include <glm/glm.hpp>

#include "core/scene/scene.h"
#include "core/surfels/surfels.h"

namespace lightlink::links {

inline constexpr std::uint32_t kNoSurfel = std::numeric_limits<std::uint32_t>::max();

class SurfelLocator {
 public:
  static constexpr std::uint32_t kTriangleListMax = 8;

  // `scene` is the scene the surfels were placed on (hits report its mesh/triangle ids).
  SurfelLocator(const surfels::Surfels& surfels, const scene::Scene& scene);

  // The owner of a hit on triangle `triangle` of mesh `mesh` at p with visible-side normal n.
  // (u, v): the hit's barycentrics on that triangle (Embree's convention, as Hit::u/v).
  std::uint32_t ownerOfHit(std::uint32_t mesh, std::uint32_t triangle, float u, float v, const glm::vec3& p,
                           const glm::vec3& n) const;

  // Nearest surfel to p whose normal is within ~60 degrees of n (unit); falls back to a
  // wider search, then to the nearest surfel regardless of normal, then kNoSurfel.
  std::uint32_t owner(const glm::vec3& p, const glm::vec3& n) const;

  float cellSize() const { return cell_; }

 private:
  glm::ivec3 cellOf(const glm::vec3& p) const;
  void buildTriangleLists(const surfels::Surfels& surfels, const scene::Scene& scene);
  std::uint32_t search(const glm::vec3& p, const glm::vec3& n, int radius, float min_cos) const;

  glm::vec3 origin_{0.0f};
  float cell_ = 1.0f;
  float inv_cell_ = 1.0f;
  glm::ivec3 dims_{1};
  std::vector<std::uint32_t> cell_begin_;  // size cells + 1
  std::vector<std::uint32_t> ids_;         // surfel ids grouped by cell, ascending within a cell
  // Positions and normals in the same cell order: a query scans contiguous memory instead
  // of gathering from the surfel arrays (the owner lookup runs once per link ray).
  std::vector<glm::vec3> cell_position_;
  std::vector<glm::vec3> cell_normal_;
  // Per-triangle surfel lists (CSR over global triangle ids = mesh_first_[mesh] + triangle);
  // lists longer than kTriangleListMax are left empty and answered by the grid.
  std::vector<std::uint32_t> mesh_first_;
  std::vector<std::uint32_t> tri_begin_;
  std::vector<std::uint32_t> tri_surfel_;
  std::vector<glm::vec3> tri_position_;
  std::vector<std::uint8_t> tri_use_grid_;
  // Triangles with more than kTriangleListMax surfels: a g x g grid over (u, v) each.
  struct BigTriangle {
    std::uint32_t g = 0;           // cells per side
    std::uint32_t first_cell = 0;  // into big_cell_begin_
  };
  std::vector<std::uint32_t> big_of_tri_;  // global triangle -> index into big_, or kNoSurfel
  std::vector<BigTriangle> big_;
  std::vector<std::uint32_t> big_cell_begin_;  // CSR over all big triangles' cells
  std::vector<std::uint32_t> big_surfel_;
  std::vector<glm::vec3> big_position_;
  std::uint32_t ownerOnBigTriangle(const BigTriangle& big, float u, float v, const glm::vec3& p) const;
};

}  // namespace lightlink::links
