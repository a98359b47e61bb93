#include "core/charts/rasterize.h"

namespace lightlink::charts {

AtlasCheck checkAtlas(const AtlasTriangles& tris, int width, int height, int gutter) {
  constexpr int kBand = 256;
  const int r = width, rows_total = height;
  const int halo = std::max(gutter, 0);
  const std::size_t n = tris.chart.size();
  AtlasCheck out;
  out.chart_texels.assign(tris.chart_count, 0);
  const int bands = (rows_total + kBand - 1) / kBand;

  // Bucket triangles by the bands their rows (plus the gutter halo) reach: counting sort.
  std::vector<std::uint32_t> start(static_cast<std::size_t>(bands) + 1, 0);
  auto bandRange = [&](std::size_t t, int& b0, int& b1) {
    const glm::dvec2* q = &tris.texels[3 * t];
    const double ymin = std::min({q[0].y, q[1].y, q[2].y}), ymax = std::max({q[0].y, q[1].y, q[2].y});
    const int y0 = std::clamp(static_cast<int>(std::floor(ymin)) - 1 - halo, 0, rows_total - 1);
    const int y1 = std::clamp(static_cast<int>(std::floor(ymax)) + 1 + halo, 0, rows_total - 1);
    b0 = y0 / kBand;
    b1 = y1 / kBand;
  };
  for (std::size_t t = 0; t < n; ++t) {
    int b0, b1;
    bandRange(t, b0, b1);
    for (int b = b0; b <= b1; ++b) ++start[static_cast<std::size_t>(b) + 1];
  }
  for (std::size_t i = 1; i < start.size(); ++i) start[i] += start[i - 1];
  std::vector<std::uint32_t> items(start.back());
  {
    std::vector<std::uint32_t> fill(start.begin(), start.end() - 1);
    for (std::size_t t = 0; t < n; ++t) {
      int b0, b1;
      bandRange(t, b0, b1);
      for (int b = b0; b <= b1; ++b) items[fill[static_cast<std::size_t>(b)]++] = static_cast<std::uint32_t>(t);
    }
  }

  // owner: chart + 1 per texel (0 = empty), kClash when two charts touch it.
  constexpr std::uint32_t kClash = 0xffffffffu;
  std::vector<std::uint32_t> owner, center;
  for (int b = 0; b < bands; ++b) {
    const int row0 = b * kBand, row1 = std::min(rows_total, row0 + kBand);
    const int ext0 = std::max(0, row0 - halo), ext1 = std::min(rows_total, row1 + halo);
    const std::size_t rows = static_cast<std::size_t>(ext1 - ext0);
    owner.assign(rows * r, 0);
    center.assign(static_cast<std::size_t>(row1 - row0) * r, 0);
    for (std::uint32_t i = start[b]; i < start[b + 1]; ++i) {
      const std::uint32_t t = items[i];
      const glm::dvec2* q = &tris.texels[3 * t];
      const std::uint32_t c = tris.chart[t];
      if (c != kNoChart) {
        forEachConservativeTexel(q, r, rows_total, ext0, ext1, [&](int x, int y) {
          std::uint32_t& o = owner[static_cast<std::size_t>(y - ext0) * r + x];
          if (o == 0) {
            o = c + 1;
          } else if (o != c + 1) {
            o = kClash;
          }
        });
      }
      forEachCenterTexel(q, r, rows_total, row0, row1, [&](int x, int y) {
        std::uint32_t& o = center[static_cast<std::size_t>(y - row0) * r + x];
        if (o == 0) {
          o = t + 1;
          ++out.center_texels;
        } else if (o != kClash) {
          o = kClash;
          ++out.triangle_overlap_texels;
        }
      });
    }
    for (int y = row0; y < row1; ++y) {
      for (int x = 0; x < r; ++x) {
        const std::uint32_t o = owner[static_cast<std::size_t>(y - ext0) * r + x];
        if (o == 0) continue;
        ++out.covered_texels;
        if (o == kClash) {
          ++out.chart_overlap_texels;
          continue;
        }
        ++out.chart_texels[o - 1];
        bool violated = false;
        for (int dy = std::max(-halo, ext0 - y); dy <= halo && y + dy < ext1 && !violated; ++dy) {
          const std::uint32_t* row = &owner[static_cast<std::size_t>(y + dy - ext0) * r];
          for (int dx = std::max(-halo, -x); dx <= halo && x + dx < r; ++dx) {
            const std::uint32_t other = row[x + dx];
            if (other != 0 && other != o) {
              violated = true;
              break;
            }
          }
        }
        out.gutter_violations += violated;
      }
    }
  }
  return out;
}

}  // namespace lightlink::charts
