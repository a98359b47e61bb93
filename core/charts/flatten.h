// Flattening: gives every chart a 2D parameterization in metres (1 uv unit = 1 m of
// surface on average over the chart), with no flipped triangles, no self-overlap and a
// bounded area stretch.
//
// Near-planar charts (every face normal within `planar_deg` of the area-weighted chart
// normal) are projected onto that best-fit plane. All others get a least squares conformal
// map (LSCM, Levy et al. 2002): per triangle the residual of the Cauchy-Riemann equations,
// grad v - rot90(grad u), weighted by the triangle area, summed and minimised with two
// border vertices pinned (the two farthest apart), as one sparse normal-equation solve
// (Eigen SimplicialLDLT). The chart is then scaled so its uv area equals its surface area.
//
// A chart is accepted only if every triangle keeps its orientation (positive uv area),
// no two triangles overlap in uv, and every triangle's area stretch
// max(r, 1/r), r = (uv area / surface area) / (chart uv area / chart surface area),
// is at most `max_area_stretch`; with 8 or more faces it must also cover at least
// `min_box_fill` of its minimal-area bounding box (long curved strips and ragged charts
// waste atlas space that splitting them recovers). Otherwise it is cut in two across its principal axis at
// the area median, each connected piece is flattened again, and so on; a single triangle
// always passes, so this terminates.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include <glm/glm.hpp>

#include "core/charts/mesh_prep.h"

namespace lightlink::charts {

struct Chart {
  std::uint32_t mesh = 0;                     // index into Scene::meshes
  std::vector<std::uint32_t> faces;           // PreparedMesh face ids, ascending
  std::vector<std::uint32_t> vertices;        // PreparedMesh vertex ids, ascending
  std::vector<std::uint32_t> local_corners;   // 3 per face, indices into `vertices`
  std::vector<glm::dvec2> uv;                 // per local vertex; metres, later texels
  double area_m2 = 0.0;                       // surface area
  bool planar = false;                        // projected (true) or LSCM (false)
};

struct FlattenOptions {
  double planar_deg = 5.0;          // charts flatter than this are projected, not solved
  double max_area_stretch = 2.0;    // per-triangle limit, see above
  double min_box_fill = 0.0;        // charts of 8+ faces filling less of their minimal box are split
};

struct FlattenStats {
  std::size_t planar = 0;
  std::size_t lscm = 0;
  std::size_t splits = 0;           // charts cut in two because they failed a check
};

// Distortion of one triangle's map from the surface to uv, relative to a chart-wide
// uv-per-surface area ratio (1 = the chart's mean texel density).
struct TriangleDistortion {
  double signed_area_ratio;   // (uv area / surface area) / chart ratio; <= 0 means flipped
  double area_stretch;        // max(r, 1/r) of the above; 1 = no stretch, inf if flipped
  double angle_distortion;    // sigma_max / sigma_min of the Jacobian; 1 = conformal
};
TriangleDistortion triangleDistortion(const glm::dvec3& p0, const glm::dvec3& p1, const glm::dvec3& p2,
                                      const glm::dvec2& q0, const glm::dvec2& q1, const glm::dvec2& q2,
                                      double chart_area_ratio);

// True if two triangles of the chart overlap in uv (interiors intersect), tested for all
// pairs that do not share an edge, through a uniform grid over the chart.
bool chartSelfOverlaps(const Chart& chart);

// Flattens the faces of one segmented chart (any set of faces of `mesh`), appending one or
// more accepted charts to `out`.
void flattenChart(const PreparedMesh& mesh, std::vector<std::uint32_t> faces, std::uint32_t mesh_index,
                  const FlattenOptions& options, std::vector<Chart>& out, FlattenStats& stats);

}  // namespace lightlink::charts
