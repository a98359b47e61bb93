#include "core/charts/preview_png.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

#include "core/charts/rasterize.h"
#include "core/common/png.h"

namespace lightlink::charts {
namespace {

// A well-spread, stable colour per id (integer hash), kept away from black and white.
glm::u8vec3 idColour(std::uint32_t id) {
  std::uint32_t h = id * 2654435761u + 0x9e3779b9u;
  h ^= h >> 15;
  h *= 2246822519u;
  h ^= h >> 13;
  return {static_cast<std::uint8_t>(64 + (h & 0xff) * 3 / 4), static_cast<std::uint8_t>(64 + ((h >> 8) & 0xff) * 3 / 4),
          static_cast<std::uint8_t>(64 + ((h >> 16) & 0xff) * 3 / 4)};
}

}  // namespace

Status writeChartPreviewPng(const scene::Scene& scene, const LightmapAtlas& atlas, const std::string& png_path,
                            int max_size) {
  if (atlas.resolution <= 0 || max_size <= 0)
    return invalidInput("chart preview: resolution {} / max size {} must be positive", atlas.resolution, max_size);
  // Pages stacked along v, scaled down as a whole so the taller side is at most max_size.
  const int tall = atlas.height();
  const double scale = std::min(1.0, double(max_size) / double(tall));
  const int width = std::max(1, static_cast<int>(atlas.resolution * scale));
  const int height = std::max(1, static_cast<int>(tall * scale));
  const glm::dvec2 size(width, height);
  std::vector<std::uint8_t> rgb(static_cast<std::size_t>(width) * height * 3, 40);
  auto put = [&](int x, int y, glm::u8vec3 c) {
    std::uint8_t* p = &rgb[(static_cast<std::size_t>(y) * width + x) * 3];
    p[0] = c.x;
    p[1] = c.y;
    p[2] = c.z;
  };
  for (std::size_t m = 0; m < scene.meshes.size() && m < atlas.meshes.size(); ++m) {
    const scene::MeshInstance& mesh = scene.meshes[m];
    if (!mesh.is_static || mesh.uv1.empty()) continue;
    const std::vector<std::uint32_t>& charts = atlas.meshes[m].triangle_chart;
    for (std::size_t t = 0; t < mesh.triangleCount(); ++t) {
      glm::dvec2 q[3];
      for (int k = 0; k < 3; ++k) q[k] = glm::dvec2(mesh.uv1[mesh.indices[3 * t + k]]) * size;
      const std::uint32_t chart = t < charts.size() ? charts[t] : kNoChart;
      const glm::u8vec3 fill = idColour(chart != kNoChart ? chart : static_cast<std::uint32_t>(m) + 0x10000u);
      forEachConservativeTexel(q, width, height, 0, height, [&](int x, int y) { put(x, y, fill); });
    }
  }
  // Wireframe after all fills so edges stay visible; DDA lines, one sample per pixel step,
  // marked first so a shared edge is darkened once.
  std::vector<std::uint8_t> wire(static_cast<std::size_t>(width) * height, 0);
  for (std::size_t m = 0; m < scene.meshes.size() && m < atlas.meshes.size(); ++m) {
    const scene::MeshInstance& mesh = scene.meshes[m];
    if (!mesh.is_static || mesh.uv1.empty()) continue;
    for (std::size_t t = 0; t < mesh.triangleCount(); ++t) {
      for (int k = 0; k < 3; ++k) {
        const glm::dvec2 a = glm::dvec2(mesh.uv1[mesh.indices[3 * t + k]]) * size;
        const glm::dvec2 b = glm::dvec2(mesh.uv1[mesh.indices[3 * t + (k + 1) % 3]]) * size;
        const int steps = std::max(1, static_cast<int>(std::ceil(std::max(std::abs(b.x - a.x), std::abs(b.y - a.y)))));
        for (int i = 0; i <= steps; ++i) {
          const glm::dvec2 p = a + (b - a) * (static_cast<double>(i) / steps);
          const int x = static_cast<int>(std::floor(p.x)), y = static_cast<int>(std::floor(p.y));
          if (x < 0 || y < 0 || x >= width || y >= height) continue;
          wire[static_cast<std::size_t>(y) * width + x] = 1;
        }
      }
    }
  }
  for (std::size_t i = 0; i < wire.size(); ++i)
    if (wire[i])
      for (int c = 0; c < 3; ++c) rgb[3 * i + c] = static_cast<std::uint8_t>(rgb[3 * i + c] / 3);
  return writePngRgb8(png_path, width, height, rgb, "chart preview");
}

}  // namespace lightlink::charts
