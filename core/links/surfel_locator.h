// SurfelLocator: which surfel owns a point on the static geometry.
//
// Link generation traces rays from caches and must credit each hit to the surfel that
// stands for that piece of surface. Surfels are (after relaxation) close to a Poisson-disc
// set, so the owner is the nearest surfel on the same side of the same surface: the
// nearest one whose normal agrees with the hit's shading side. A double-sided surface has
// surfels on each side (surfels.h), and a hit on its back is owned by a back-side surfel:
// the tables below are kept per side ("side meshes"). A dense uniform grid over
// the surfels (cell ~2 surfel spacings, CSR layout: one offsets array, one id array) makes
// the query a scan of 27 cells of a few surfels each, with no allocation per query. The
// locator copies what it needs; the Surfels may go away after construction.
//
// Most hits are cheaper than that: the ray tracer already says which triangle was hit, and
// every triangle answers from a table of its own, an owner raster. A triangle holding one
// surfel, or none (its area went into a neighbour's slice; it is then represented by the
// surfel nearest its centroid), has a 1 x 1 raster: that surfel. A triangle with more
// (walls of a box, floors of a level) bins them in a g x g grid over its barycentric square
// (g = ceil(sqrt(surfels)), so a cell is about one surfel spacing), and each cell is split
// r x r (r = kRaster, less when the rasters would not fit their memory budget): each raster
// cell holds the surfel nearest to its centre among the 3 x 3 cells around it (the whole
// triangle when those are empty). A hit costs one 16-byte record and one table load, where
// a scan of ~8-20 candidates per hit would cost more than any phase of link generation but
// the tracing (precompute_bench's "credit" phase on the Cornell box; zdm2's hits land mostly
// on small triangles, which the 1 x 1 rasters answer).
//
// The raster is a partition of each big triangle into patches of ~1/r^2 of a surfel's area,
// each given to the surfel nearest its centre: it differs from the nearest surfel to the hit
// point itself only in a band of half a raster cell along the Voronoi edges, and there by at
// most one raster cell diagonal in distance (triangle inequality; tests/links checks that
// bound and how rarely the two differ). Links sum hits over tree nodes of many surfels, so
// that band moves visibility between neighbouring surfels of the same node almost always.
// The 3D grid remains for hits without a triangle answer.
#pragma once

#include <cstddef>
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
  // Raster cells per big-triangle cell and side, and the most raster cells all big triangles
  // may hold together (4 bytes each); past that budget r halves (down to 1).
  static constexpr std::uint32_t kRaster = 4;
  static constexpr std::size_t kRasterBudget = std::size_t(1) << 24;

  // `scene` is the scene the surfels were placed on (hits report its mesh/triangle ids).
  // `raster_budget`: the most raster cells in all (tests lower it to see r shrink).
  // `narrow_raster`: keep the raster in 16 bits when the surfel ids fit (tests turn it off to
  // compare the two widths).
  SurfelLocator(const surfels::Surfels& surfels, const scene::Scene& scene,
                std::size_t raster_budget = kRasterBudget, bool narrow_raster = true);

  // The side mesh of a hit on mesh `mesh`: the mesh itself for its front (the side its winding
  // normal faces), mesh + meshes for the back of a double-sided mesh, whose back-side surfels
  // have their own rasters (a single-sided mesh's back blocks, it owns nothing). The `mesh`
  // argument of ownerOfHit, rasterSlot and the tests' queries below is a side mesh.
  std::uint32_t sideMesh(std::uint32_t mesh, bool back) const { return back ? mesh + mesh_count_ : mesh; }

  // The owner of a hit on triangle `triangle` of mesh `mesh` at p with visible-side normal n.
  // (u, v): the hit's barycentrics on that triangle (Embree's convention, as Hit::u/v).
  // Inline: it runs once per link ray, and a triangle's answer is one record and one load.
  std::uint32_t ownerOfHit(std::uint32_t mesh, std::uint32_t triangle, float u, float v, const glm::vec3& p,
                           const glm::vec3& n) const {
    const std::uint32_t k = rasterSlot(mesh, triangle, u, v);
    const std::uint32_t s = k != kNoSurfel ? slotOwner(k) : kNoSurfel;
    return s != kNoSurfel ? s : owner(p, n);
  }

  // ownerOfHit in two steps, for a caller that looks up many hits at once and wants the
  // raster loads (cache misses, most of the lookup's time) in flight together: the raster
  // slot of a hit (kNoSurfel for a triangle without a raster: ask ownerOfHit), then the
  // surfel in a slot (kNoSurfel for a slot beyond a hypotenuse: ask ownerOfHit).
  std::uint32_t rasterSlot(std::uint32_t mesh, std::uint32_t triangle, float u, float v) const {
    const std::uint32_t t = globalTriangle(mesh, triangle);
    if (t == kNoSurfel || raster_ref_[t].first == kNoSurfel) return kNoSurfel;
    return rasterIndex(raster_ref_[t], u, v);
  }
  std::uint32_t slotOwner(std::uint32_t slot) const {
    if (!raster16_.empty()) return raster16_[slot] == kNoSurfel16 ? kNoSurfel : raster16_[slot];
    return raster_[slot];
  }
  const void* slotAddress(std::uint32_t slot) const {
    return raster16_.empty() ? static_cast<const void*>(raster_.data() + slot) : raster16_.data() + slot;
  }

  // The tables behind rasterSlot and slotOwner, for a caller that reads them for 16 hits at
  // a time with gathers (hit_credit.cpp): rasterSlot is t = mesh_first[side mesh] + triangle
  // (valid when mesh + 1 < mesh_first_count and t < mesh_first[mesh_first_count - 1]), then
  // the triangle's raster {first, size} = raster_ref[4 t], raster_ref[4 t + 1] (first
  // kNoSurfel: none), and the slot as rasterIndex computes it (size_f = float(size),
  // max_f = float(size - 1)).
  struct RasterTables {
    const std::uint32_t* mesh_first = nullptr;
    std::uint32_t mesh_first_count = 0;
    std::uint32_t mesh_count = 0;  // scene meshes: a back hit's side mesh is mesh + mesh_count
    const std::uint32_t* raster_ref = nullptr;
    // One of the two: 16-bit cells (0xffff for kNoSurfel, and one more cell after the last,
    // so that a 4-byte load of the last cell stays inside) or 32-bit ones.
    const std::uint16_t* raster16 = nullptr;
    const std::uint32_t* raster32 = nullptr;
  };
  RasterTables rasterTables() const;

  // Nearest surfel to p whose normal is within ~60 degrees of n (unit); falls back to a
  // wider search, then to the nearest surfel regardless of normal, then kNoSurfel.
  std::uint32_t owner(const glm::vec3& p, const glm::vec3& n) const;

  // ownerOfHit with a big triangle's raster replaced by the scan it samples: the nearest
  // candidate of the 3 x 3 cells around (u, v) to p itself. What tests/links compares the
  // raster with.
  std::uint32_t ownerOfHitNearest(std::uint32_t mesh, std::uint32_t triangle, float u, float v,
                                  const glm::vec3& p, const glm::vec3& n) const;
  // The largest diagonal (metres) of a raster cell of that big triangle, 0 for a small one:
  // the raster owner is at most this much farther from a hit on it than the nearest.
  float rasterCellDiagonal(std::uint32_t mesh, std::uint32_t triangle) const;
  // Raster cells per side of that big triangle's raster (g r), 0 for a small one. Cell (fu, fv)
  // has its centre at ((fu + 0.5) / size, (fv + 0.5) / size), computed as
  // (float(f) + 0.5f) * (1.0f / float(size)).
  std::uint32_t rasterSize(std::uint32_t mesh, std::uint32_t triangle) const;

  float cellSize() const { return cell_; }
  // Raster cells over all triangles (1 for each small one), and r (raster cells per
  // big-triangle cell and side): for tests and the benchmark's report.
  std::size_t rasterCellCount() const { return raster16_.empty() ? raster_.size() : raster16_.size() - 1; }
  // Bytes per raster cell: 2 when the raster is kept in 16 bits, else 4.
  std::size_t rasterCellBytes() const { return raster16_.empty() ? 4 : 2; }
  std::uint32_t rasterFactor() const { return raster_factor_; }
  // Surfels it was built over (link generation checks them against the tree).
  std::size_t surfelCount() const { return surfel_count_; }

 private:
  std::size_t surfel_count_ = 0;
  glm::ivec3 cellOf(const glm::vec3& p) const;
  void buildTriangleTables(const surfels::Surfels& surfels, const scene::Scene& scene);
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
  // Global triangle ids: mesh_first_[side mesh] + triangle (2 meshes + 1 entries).
  std::vector<std::uint32_t> mesh_first_;
  std::uint32_t mesh_count_ = 0;
  // (mesh, triangle) as a global id, kNoSurfel when either is out of range.
  std::uint32_t globalTriangle(std::uint32_t mesh, std::uint32_t triangle) const {
    if (mesh + 1 >= mesh_first_.size()) return kNoSurfel;
    const std::uint32_t t = mesh_first_[mesh] + triangle;
    return t < mesh_first_[mesh + 1] ? t : kNoSurfel;
  }
  // Triangles with more than one surfel ("big"): a g x g grid over (u, v) each, and its
  // (g r) x (g r) owner raster.
  struct BigTriangle {
    glm::vec3 v0{0.0f}, e1{0.0f}, e2{0.0f};  // as traced: P(u, v) = v0 + u e1 + v e2
    std::uint32_t g = 0;            // cells per side
    std::uint32_t gr = 0;           // raster cells per side (g r)
    std::uint32_t first_cell = 0;   // into big_cell_begin_
    std::uint32_t first_raster = 0; // into raster_
  };
  // What a hit reads to find its raster cell: 16 bytes per triangle (RasterTables::raster_ref).
  struct RasterRef {
    std::uint32_t first = kNoSurfel;  // into raster_; kNoSurfel: the triangle has no raster
    std::uint32_t size = 1;   // cells per side (g r; 1 for a one-entry triangle)
    float size_f = 1.0f;
    float max_f = 0.0f;       // size - 1, as float: the clamp of a raster coordinate
  };
  // Raster cell of (u, v), clamped to the raster (NaN lands on an edge cell).
  static std::uint32_t rasterIndex(const RasterRef& ref, float u, float v) {
    auto axis = [&](float w) {
      float x = w * ref.size_f;
      x = x < ref.max_f ? x : ref.max_f;  // also NaN -> max_f
      return static_cast<std::uint32_t>(x > 0.0f ? x : 0.0f);
    };
    return ref.first + axis(v) * ref.size + axis(u);
  }
  std::vector<std::uint32_t> big_of_tri_;  // global triangle -> index into big_, or kNoSurfel
  std::vector<BigTriangle> big_;
  std::vector<std::uint32_t> big_cell_begin_;  // CSR over all big triangles' cells
  std::vector<std::uint32_t> big_surfel_;
  std::vector<glm::vec3> big_position_;
  std::vector<std::uint32_t> raster_;  // surfel ids, all triangles' rasters in order
  // The same in 16 bits (kNoSurfel16 for kNoSurfel) when there are fewer than 65535
  // surfels, plus one padding cell (RasterTables); raster_ is then emptied.
  static constexpr std::uint16_t kNoSurfel16 = 0xffff;
  std::vector<std::uint16_t> raster16_;
  // Per global triangle, indexed directly (an index table in between was one more dependent
  // load per hit).
  std::vector<RasterRef> raster_ref_;
  std::uint32_t raster_factor_ = kRaster;
  std::size_t raster_budget_ = kRasterBudget;
  bool narrow_raster_ = true;
  void buildRasters(const scene::Scene& scene, const std::vector<std::uint32_t>& big_mesh,
                    const std::vector<std::uint32_t>& big_triangle);
  const BigTriangle* bigTriangle(std::uint32_t mesh, std::uint32_t triangle) const;  // null for a small one
  // The candidates of big-triangle cell (iu, iv): indices into big_position_ / big_surfel_ of
  // the 3 x 3 cells around it (the whole triangle when those are empty), in a fixed order.
  void cellCandidates(const BigTriangle& big, int iu, int iv, std::vector<std::uint32_t>& out) const;
  // The surfel of the candidate nearest to p, the first of equally near ones.
  std::uint32_t nearestCandidate(const std::vector<std::uint32_t>& candidates, const glm::vec3& p) const;
  // nearestCandidate over the candidates of (u, v)'s cell: what the raster samples.
  std::uint32_t scanBigTriangle(const BigTriangle& big, float u, float v, const glm::vec3& p) const;
};

}  // namespace lightlink::links
