// Rasterisation of uv triangles onto the atlas texel grid, and the atlas check built on it.
//
// Coordinates are atlas texels: texel (x, y) is the square [x, x+1) x [y, y+1), its centre
// at (x + 0.5, y + 0.5); uv1 = texel / resolution. Two rules:
//  - conservative: every texel whose closed square touches the closed triangle. Used
//    between charts: no texel may be touched by two charts (overlap), and every touched
//    texel must be more than `gutter` texels (Chebyshev) from any texel of another chart.
//  - centre sampling with a tie rule (a centre exactly on an edge belongs to the triangle
//    whose edge runs up, or left when horizontal), so a centre on an edge shared by two
//    consistently oriented triangles belongs to exactly one: a centre claimed twice means
//    two triangles overlap (folds inside a chart, or any overlap in existing uv1). These
//    centres are where the precompute places lightmap caches (paper section 4.4).
// The atlas is processed in bands of rows so memory stays ~2 x resolution x 300 x 4 bytes
// even at 16384.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <vector>

#include <glm/glm.hpp>

namespace lightlink::charts {

inline constexpr std::uint32_t kNoChart = 0xffffffffu;

// Calls fn(x, y) for every texel the closed triangle touches, clipped to [0,w) x [0,h).
// `inflate` (texels) also takes texels within that distance along x or y: the packer uses
// it so that rounding uv1 to float can never reach a texel it did not reserve.
template <typename Fn>
void forEachConservativeTexel(const glm::dvec2 q[3], int w, int h, int row_begin, int row_end, Fn&& fn,
                              double inflate = 0.0) {
  const double ymin = std::min({q[0].y, q[1].y, q[2].y}), ymax = std::max({q[0].y, q[1].y, q[2].y});
  const int y0 = std::max({static_cast<int>(std::ceil(ymin - inflate)) - 1, 0, row_begin});
  const int y1 = std::min({static_cast<int>(std::floor(ymax + inflate)), h - 1, row_end - 1});
  for (int y = y0; y <= y1; ++y) {
    // x-range of the triangle clipped to the closed strip [y, y+1]: vertices inside it
    // and the crossings of the edges with its two lines.
    double xmin = 1e300, xmax = -1e300;
    const double lo = y - inflate, hi = y + 1.0 + inflate;
    for (int k = 0; k < 3; ++k) {
      const glm::dvec2 a = q[k], b = q[(k + 1) % 3];
      if (a.y >= lo && a.y <= hi) {
        xmin = std::min(xmin, a.x);
        xmax = std::max(xmax, a.x);
      }
      for (double line : {lo, hi}) {
        if ((a.y - line) * (b.y - line) < 0.0) {
          const double x = a.x + (b.x - a.x) * (line - a.y) / (b.y - a.y);
          xmin = std::min(xmin, x);
          xmax = std::max(xmax, x);
        }
      }
    }
    if (xmin > xmax) continue;
    const int x0 = std::max(static_cast<int>(std::ceil(xmin - inflate)) - 1, 0);
    const int x1 = std::min(static_cast<int>(std::floor(xmax + inflate)), w - 1);
    for (int x = x0; x <= x1; ++x) fn(x, y);
  }
}

// Calls fn(x, y) for every texel whose centre lies inside the triangle (tie rule above).
// Triangles of either orientation are accepted.
template <typename Fn>
void forEachCenterTexel(const glm::dvec2 in[3], int w, int h, int row_begin, int row_end, Fn&& fn) {
  glm::dvec2 q[3] = {in[0], in[1], in[2]};
  const double area2 = (q[1].x - q[0].x) * (q[2].y - q[0].y) - (q[1].y - q[0].y) * (q[2].x - q[0].x);
  if (area2 == 0.0) return;
  if (area2 < 0.0) std::swap(q[1], q[2]);
  const double ymin = std::min({q[0].y, q[1].y, q[2].y}), ymax = std::max({q[0].y, q[1].y, q[2].y});
  const double xmin = std::min({q[0].x, q[1].x, q[2].x}), xmax = std::max({q[0].x, q[1].x, q[2].x});
  const int y0 = std::max({static_cast<int>(std::floor(ymin - 0.5)), 0, row_begin});
  const int y1 = std::min({static_cast<int>(std::ceil(ymax - 0.5)), h - 1, row_end - 1});
  const int x0 = std::max(static_cast<int>(std::floor(xmin - 0.5)), 0);
  const int x1 = std::min(static_cast<int>(std::ceil(xmax - 0.5)), w - 1);
  bool owns_zero[3];
  for (int k = 0; k < 3; ++k) {
    const glm::dvec2 d = q[(k + 1) % 3] - q[k];
    owns_zero[k] = d.y > 0.0 || (d.y == 0.0 && d.x < 0.0);
  }
  for (int y = y0; y <= y1; ++y) {
    const double py = y + 0.5;
    for (int x = x0; x <= x1; ++x) {
      const double px = x + 0.5;
      bool inside = true;
      for (int k = 0; k < 3 && inside; ++k) {
        const glm::dvec2 a = q[k], b = q[(k + 1) % 3];
        const double e = (b.x - a.x) * (py - a.y) - (b.y - a.y) * (px - a.x);
        inside = e > 0.0 || (e == 0.0 && owns_zero[k]);
      }
      if (inside) fn(x, y);
    }
  }
}

// Triangles in atlas texel coordinates, with the chart each belongs to (kNoChart for
// existing uv1, whose charts are unknown: only the centre test applies to them).
struct AtlasTriangles {
  std::vector<glm::dvec2> texels;        // 3 per triangle
  std::vector<std::uint32_t> chart;      // per triangle
  std::uint32_t chart_count = 0;
};

struct AtlasCheck {
  std::size_t chart_overlap_texels = 0;     // texels touched by two or more charts
  std::size_t triangle_overlap_texels = 0;  // texel centres inside two or more triangles
  std::size_t gutter_violations = 0;        // chart texels within `gutter` of another chart
  std::size_t covered_texels = 0;           // texels touched by any chart (conservative)
  std::size_t center_texels = 0;            // texel centres inside some triangle
  std::vector<std::size_t> chart_texels;    // per chart, conservative
};

AtlasCheck checkAtlas(const AtlasTriangles& tris, int width, int height, int gutter);

}  // namespace lightlink::charts
