#include "tests/charts/atlas_oracle.h"

#include <algorithm>
#include <cmath>

#include <fmt/format.h>

#include "core/charts/rasterize.h"

namespace lightlink::charts::testing {
namespace {

// Closed texel square [x, x+1] x [y, y+1] against a closed triangle: no separating axis
// among the two square axes and the three edge normals.
bool squareTouchesTriangle(int x, int y, const glm::dvec2 q[3]) {
  const glm::dvec2 sq[4] = {{x, y}, {x + 1, y}, {x + 1, y + 1}, {x, y + 1}};
  const glm::dvec2 axes[5] = {{1, 0}, {0, 1}, {-(q[1] - q[0]).y, (q[1] - q[0]).x}, {-(q[2] - q[1]).y, (q[2] - q[1]).x},
                              {-(q[0] - q[2]).y, (q[0] - q[2]).x}};
  for (const glm::dvec2& a : axes) {
    double s0 = 1e300, s1 = -1e300, t0 = 1e300, t1 = -1e300;
    for (const glm::dvec2& p : sq) {
      s0 = std::min(s0, glm::dot(a, p));
      s1 = std::max(s1, glm::dot(a, p));
    }
    for (int k = 0; k < 3; ++k) {
      t0 = std::min(t0, glm::dot(a, q[k]));
      t1 = std::max(t1, glm::dot(a, q[k]));
    }
    if (s1 < t0 || t1 < s0) return false;
  }
  return true;
}

bool strictlyInside(const glm::dvec2& p, const glm::dvec2 q[3]) {
  const double area = (q[1].x - q[0].x) * (q[2].y - q[0].y) - (q[1].y - q[0].y) * (q[2].x - q[0].x);
  for (int k = 0; k < 3; ++k) {
    const glm::dvec2 a = q[k], b = q[(k + 1) % 3];
    const double e = ((b.x - a.x) * (p.y - a.y) - (b.y - a.y) * (p.x - a.x)) / area;
    if (!(e > 1e-9)) return false;
  }
  return true;
}

}  // namespace

OracleResult checkWithOracle(const scene::Scene& scene, const LightmapAtlas& atlas) {
  OracleResult r;
  const int res = atlas.resolution, rows = atlas.height();  // pages stacked along v
  const std::size_t texels = static_cast<std::size_t>(res) * rows;
  std::vector<std::uint32_t> owner(texels, 0);  // chart + 1; kClash on collision
  std::vector<std::uint32_t> centre(texels, 0); // triangle serial + 1
  constexpr std::uint32_t kClash = 0xffffffffu;
  std::uint32_t serial = 0;
  auto problem = [&](const std::string& s) {
    if (r.first_problem.empty()) r.first_problem = s;
  };
  for (std::size_t m = 0; m < scene.meshes.size(); ++m) {
    const scene::MeshInstance& mesh = scene.meshes[m];
    if (!mesh.is_static || mesh.probe_lit) continue;
    for (const glm::vec2& t : mesh.uv1) r.out_of_range += !(t.x >= 0 && t.x <= 1 && t.y >= 0 && t.y <= 1);
    for (std::size_t t = 0; t < mesh.triangleCount(); ++t, ++serial) {
      glm::dvec2 q[3];
      for (int k = 0; k < 3; ++k) q[k] = glm::dvec2(mesh.uv1[mesh.indices[3 * t + k]]) * glm::dvec2(res, rows);
      const double area = (q[1].x - q[0].x) * (q[2].y - q[0].y) - (q[1].y - q[0].y) * (q[2].x - q[0].x);
      if (!(area > 0.0)) {
        ++r.flipped;
        problem(fmt::format("mesh {} triangle {} flipped (2*area {})", m, t, area));
        if (area == 0.0) continue;  // mirrored existing uv1 still covers texels
      }
      const std::uint32_t chart = atlas.meshes[m].triangle_chart[t];
      const int x0 = std::max(0, static_cast<int>(std::floor(std::min({q[0].x, q[1].x, q[2].x}))) - 1);
      const int x1 = std::min(res - 1, static_cast<int>(std::floor(std::max({q[0].x, q[1].x, q[2].x}))) + 1);
      const int y0 = std::max(0, static_cast<int>(std::floor(std::min({q[0].y, q[1].y, q[2].y}))) - 1);
      const int y1 = std::min(rows - 1, static_cast<int>(std::floor(std::max({q[0].y, q[1].y, q[2].y}))) + 1);
      for (int y = y0; y <= y1; ++y) {
        for (int x = x0; x <= x1; ++x) {
          const std::size_t i = static_cast<std::size_t>(y) * res + x;
          if (chart != kNoChart && squareTouchesTriangle(x, y, q)) {
            if (owner[i] == 0) {
              owner[i] = chart + 1;
            } else if (owner[i] != chart + 1 && owner[i] != kClash) {
              problem(fmt::format("texel ({}, {}) touched by charts {} and {}", x, y, owner[i] - 1, chart));
              owner[i] = kClash;
              ++r.chart_overlap_texels;
            }
          }
          if (strictlyInside({x + 0.5, y + 0.5}, q)) {
            if (centre[i] != 0 && centre[i] != serial + 1) {
              problem(fmt::format("texel centre ({}, {}) inside two triangles", x, y));
              ++r.center_overlaps;
            }
            centre[i] = serial + 1;
          }
        }
      }
    }
  }
  const int g = atlas.gutter_texels;
  for (int y = 0; y < rows; ++y) {
    for (int x = 0; x < res; ++x) {
      const std::uint32_t o = owner[static_cast<std::size_t>(y) * res + x];
      if (o == 0) continue;
      ++r.covered;
      for (int dy = -g; dy <= g; ++dy) {
        for (int dx = -g; dx <= g; ++dx) {
          const int xx = x + dx, yy = y + dy;
          if (xx < 0 || yy < 0 || xx >= res || yy >= rows) continue;
          const std::uint32_t other = owner[static_cast<std::size_t>(yy) * res + xx];
          if (other != 0 && other != o) {
            ++r.gutter_violations;
            problem(fmt::format("texels ({}, {}) and ({}, {}) of different charts within the {}-texel gutter", x, y,
                                xx, yy, g));
          }
        }
      }
    }
  }
  return r;
}

}  // namespace lightlink::charts::testing
