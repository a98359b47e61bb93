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
// bins them in a g x g grid over its barycentric square (g = ceil(sqrt(surfels))), and the
// owner of a hit is the nearest surfel among the 3 x 3 cells around the hit's own (u, v) cell
// (the whole triangle when those are empty), ties to the first in cell order: ~20 candidates.
//
// That definition is answered faster than by scanning the ~20 candidates, with the same
// answer for every hit: each cell is split kFine x kFine, and each fine cell keeps only the
// candidates that can be nearest somewhere in it. A candidate j is dropped when one other
// candidate i is closer than j at every point of the fine cell, with a margin that covers
// float rounding of the query's squared distances and hit points up to a stated distance off
// the triangle (the difference of two squared distances is affine in the point, so checking
// the cell's corners suffices). Removing candidates that are never the nearest changes
// neither the nearest nor the first of equally near ones. A hit outside what the lists were
// proven for (off the triangle by more than the margin, barycentrics out of range) takes the
// full scan. ~8 candidates per hit instead of ~20 on the Cornell box (6 on zdm2); the whole
// locator builds in 8-16 ms for the Cornell box (bench/precompute prints it).
// The 3D grid remains for hits without a triangle answer.
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
  // Fine cells per big-triangle cell and side (a power of two: the fine cell of a hit then
  // lies inside its cell for every float (u, v)). 1 and 2 measured the same on the Cornell
  // box (links 0.75 vs 0.78 s); 1 builds 4x fewer lists.
  static constexpr std::uint32_t kFine = 1;
  static_assert(kFine > 0 && (kFine & (kFine - 1)) == 0, "kFine must be a power of two");

  // `scene` is the scene the surfels were placed on (hits report its mesh/triangle ids).
  SurfelLocator(const surfels::Surfels& surfels, const scene::Scene& scene);

  // The owner of a hit on triangle `triangle` of mesh `mesh` at p with visible-side normal n.
  // (u, v): the hit's barycentrics on that triangle (Embree's convention, as Hit::u/v).
  std::uint32_t ownerOfHit(std::uint32_t mesh, std::uint32_t triangle, float u, float v, const glm::vec3& p,
                           const glm::vec3& n) const;

  // Nearest surfel to p whose normal is within ~60 degrees of n (unit); falls back to a
  // wider search, then to the nearest surfel regardless of normal, then kNoSurfel.
  std::uint32_t owner(const glm::vec3& p, const glm::vec3& n) const;

  // ownerOfHit by the definition alone, scanning every candidate of a big triangle's cells:
  // the reference the pruned fine lists reproduce exactly (tests/links).
  std::uint32_t ownerOfHitExhaustive(std::uint32_t mesh, std::uint32_t triangle, float u, float v,
                                     const glm::vec3& p, const glm::vec3& n) const;

  float cellSize() const { return cell_; }
  // Fine cells of big triangles that hold a pruned list, and their mean length (what a hit on
  // a big triangle scans): for tests and the benchmark's report.
  std::size_t fineListCount() const;
  double meanFineListLength() const;

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
    glm::vec3 v0{0.0f}, e1{0.0f}, e2{0.0f};  // as traced: P(u, v) = v0 + u e1 + v e2
    float max_offset = 0.0f;   // fine lists hold for hits within this (per axis) of P(u, v)
    std::uint32_t g = 0;           // cells per side
    std::uint32_t first_cell = 0;  // into big_cell_begin_
    std::uint32_t first_fine = 0;  // into fine_begin_; (g * kFine)^2 fine cells
  };
  std::vector<std::uint32_t> big_of_tri_;  // global triangle -> index into big_, or kNoSurfel
  std::vector<BigTriangle> big_;
  std::vector<std::uint32_t> big_cell_begin_;  // CSR over all big triangles' cells
  std::vector<std::uint32_t> big_surfel_;
  std::vector<glm::vec3> big_position_;
  std::vector<std::uint32_t> fine_begin_;  // CSR over all big triangles' fine cells; empty: full scan
  // Indices into big_position_ / big_surfel_ (ascending per list): 4 bytes per candidate
  // keep the lists small enough to stay in cache next to the 12-byte positions they point
  // into (16-byte {position, id} entries measured slower: the lookups became cache misses).
  std::vector<std::uint32_t> fine_candidate_;
  void buildFineLists(const scene::Scene& scene, const std::vector<std::uint32_t>& big_mesh,
                      const std::vector<std::uint32_t>& big_triangle);
  std::uint32_t ownerOnBigTriangle(const BigTriangle& big, float u, float v, const glm::vec3& p) const;
  std::uint32_t scanBigTriangle(const BigTriangle& big, float u, float v, const glm::vec3& p) const;
  template <bool kExhaustive>
  std::uint32_t ownerOfHitImpl(std::uint32_t mesh, std::uint32_t triangle, float u, float v, const glm::vec3& p,
                               const glm::vec3& n) const;
  // Fine lists hold for barycentrics in [-kBaryCheck, 1 + kBaryCheck].
  static constexpr float kBaryCheck = 1e-5f;
};

}  // namespace lightlink::links
