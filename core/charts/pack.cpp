#include "core/charts/pack.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>

#include <tbb/parallel_for.h>

#include "core/charts/rasterize.h"

namespace lightlink::charts {
namespace {

// Longest chart side (texels) a mask is built for: far beyond any atlas (16384), so only
// charts that could never fit are refused, and the int texel coordinates cannot overflow.
constexpr double kMaxPackSide = double(1 << 24);

double cross(const glm::dvec2& o, const glm::dvec2& a, const glm::dvec2& b) {
  return (a.x - o.x) * (b.y - o.y) - (a.y - o.y) * (b.x - o.x);
}

// Andrew's monotone chain, counter-clockwise, collinear points dropped.
std::vector<glm::dvec2> convexHull(std::vector<glm::dvec2> pts) {
  std::sort(pts.begin(), pts.end(), [](const glm::dvec2& a, const glm::dvec2& b) {
    return a.x != b.x ? a.x < b.x : a.y < b.y;
  });
  if (pts.size() < 3) return pts;
  std::vector<glm::dvec2> hull(2 * pts.size());
  std::size_t k = 0;
  for (std::size_t i = 0; i < pts.size(); ++i) {
    while (k >= 2 && cross(hull[k - 2], hull[k - 1], pts[i]) <= 0.0) --k;
    hull[k++] = pts[i];
  }
  for (std::size_t i = pts.size() - 1, t = k + 1; i > 0; --i) {
    while (k >= t && cross(hull[k - 2], hull[k - 1], pts[i - 1]) <= 0.0) --k;
    hull[k++] = pts[i - 1];
  }
  hull.resize(k - 1);
  return hull;
}

}  // namespace

void alignToMinimalBox(Chart& chart) {
  const std::vector<glm::dvec2> hull = convexHull(chart.uv);
  // The minimal box has a side on a hull edge: try each edge direction.
  glm::dvec2 best_dir(1.0, 0.0);
  double best_area = std::numeric_limits<double>::max();
  for (std::size_t i = 0; i < hull.size(); ++i) {
    glm::dvec2 e = hull[(i + 1) % hull.size()] - hull[i];
    const double len = glm::length(e);
    if (!(len > 0.0)) continue;
    e /= len;
    double x0 = std::numeric_limits<double>::max(), x1 = -x0, y0 = x0, y1 = -x0;
    for (const glm::dvec2& p : hull) {
      const double u = glm::dot(p, e), v = e.x * p.y - e.y * p.x;
      x0 = std::min(x0, u);
      x1 = std::max(x1, u);
      y0 = std::min(y0, v);
      y1 = std::max(y1, v);
    }
    const double area = (x1 - x0) * (y1 - y0);
    if (area < best_area * (1.0 - 1e-9)) {
      best_area = area;
      best_dir = (x1 - x0) >= (y1 - y0) ? e : glm::dvec2(-e.y, e.x);  // longer side along x
    }
  }
  // Rotation taking best_dir to +x (det +1: orientation is kept).
  glm::dvec2 lo(std::numeric_limits<double>::max());
  for (glm::dvec2& p : chart.uv) {
    p = {best_dir.x * p.x + best_dir.y * p.y, best_dir.x * p.y - best_dir.y * p.x};
    lo = glm::min(lo, p);
  }
  for (glm::dvec2& p : chart.uv) p -= lo;
}

namespace {

// Slack (texels) added around every triangle when building masks: uv1 is stored as float,
// whose rounding at 16384 texels is ~1e-3 texel.
constexpr double kMaskSlack = 4e-3;

// Column and row profiles of a chart's conservative mask: per column the lowest texel and
// one past the highest, per row the leftmost and one past the rightmost.
struct Mask {
  int w = 0, h = 0;
  std::vector<int> bottom, top, left, right;
};

Mask chartMask(const Chart& chart, double texel_m) {
  glm::dvec2 ext(0.0);
  for (const glm::dvec2& p : chart.uv) ext = glm::max(ext, p);
  Mask m;
  m.w = static_cast<int>(std::floor(ext.x / texel_m + 0.5 + kMaskSlack)) + 1;
  m.h = static_cast<int>(std::floor(ext.y / texel_m + 0.5 + kMaskSlack)) + 1;
  m.bottom.assign(static_cast<std::size_t>(m.w), m.h);
  m.top.assign(static_cast<std::size_t>(m.w), 0);
  m.left.assign(static_cast<std::size_t>(m.h), m.w);
  m.right.assign(static_cast<std::size_t>(m.h), 0);
  for (std::size_t fi = 0; fi < chart.faces.size(); ++fi) {
    glm::dvec2 q[3];
    for (int k = 0; k < 3; ++k) q[k] = chart.uv[chart.local_corners[3 * fi + k]] / texel_m + glm::dvec2(0.5);
    forEachConservativeTexel(
        q, m.w, m.h, 0, m.h,
        [&](int x, int y) {
          m.bottom[static_cast<std::size_t>(x)] = std::min(m.bottom[static_cast<std::size_t>(x)], y);
          m.top[static_cast<std::size_t>(x)] = std::max(m.top[static_cast<std::size_t>(x)], y + 1);
          m.left[static_cast<std::size_t>(y)] = std::min(m.left[static_cast<std::size_t>(y)], x);
          m.right[static_cast<std::size_t>(y)] = std::max(m.right[static_cast<std::size_t>(y)], x + 1);
        },
        kMaskSlack);
  }
  // A column (row) the chart does not reach (possible only at sub-texel gaps between
  // pieces of the conservative cover) constrains nothing: make it empty-but-harmless.
  for (int x = 0; x < m.w; ++x)
    if (m.bottom[static_cast<std::size_t>(x)] >= m.top[static_cast<std::size_t>(x)])
      m.bottom[static_cast<std::size_t>(x)] = m.h, m.top[static_cast<std::size_t>(x)] = 0;
  for (int y = 0; y < m.h; ++y)
    if (m.left[static_cast<std::size_t>(y)] >= m.right[static_cast<std::size_t>(y)])
      m.left[static_cast<std::size_t>(y)] = m.w, m.right[static_cast<std::size_t>(y)] = 0;
  return m;
}

// Bottom/top profile of the mask turned `turns` quarter turns counter-clockwise.
// Texel (x, y) of a w x h mask goes to (h-1-y, x), (w-1-x, h-1-y), (y, w-1-x).
void turnedProfile(const Mask& m, int turns, std::vector<int>& bottom, std::vector<int>& top) {
  const int w = (turns & 1) ? m.h : m.w;
  bottom.resize(static_cast<std::size_t>(w));
  top.resize(static_cast<std::size_t>(w));
  for (int c = 0; c < w; ++c) {
    const auto i = static_cast<std::size_t>(c);
    switch (turns) {
      case 0:
        bottom[i] = m.bottom[i];
        top[i] = m.top[i];
        break;
      case 1: {  // column c <- row h-1-c; new y = old x
        const auto r = static_cast<std::size_t>(m.h - 1 - c);
        bottom[i] = m.left[r];
        top[i] = m.right[r];
        break;
      }
      case 2: {  // column c <- column w-1-c; new y = h-1-old y
        const auto r = static_cast<std::size_t>(m.w - 1 - c);
        bottom[i] = m.h - m.top[r];
        top[i] = m.h - m.bottom[r];
        break;
      }
      default: {  // column c <- row c; new y = w-1-old x
        bottom[i] = m.w - m.right[i];
        top[i] = m.w - m.left[i];
        break;
      }
    }
    if (bottom[i] >= top[i]) bottom[i] = 1 << 29, top[i] = -(1 << 29);  // empty column
  }
}

}  // namespace

namespace {

// The skyline packer of packCharts (page_rows == 0: one strip, unlimited height) and
// packChartsPaged (square pages of `resolution`, stacked along y).
int packImpl(const std::vector<Chart>& charts, double texel_m, int resolution, int gutter, bool paged,
             std::vector<Placement>& placements, const Progress* progress) {
  const std::size_t n = charts.size();
  placements.assign(n, {});
  if (resolution <= 2 * gutter) return -1;
  // The mask of a chart is its box in texels: one wider than the strip on its short side
  // cannot fit, and building it first (billions of texels at 1e-9 m) would never end.
  const double side_limit = double(resolution - 2 * gutter);
  for (const Chart& chart : charts) {
    glm::dvec2 ext(0.0);
    for (const glm::dvec2& p : chart.uv) ext = glm::max(ext, p);
    const double w = std::floor(ext.x / texel_m + 0.5 + kMaskSlack) + 1.0;
    const double h = std::floor(ext.y / texel_m + 0.5 + kMaskSlack) + 1.0;
    if (!(std::min(w, h) <= side_limit) || !(std::max(w, h) <= double(kMaxPackSide))) return -1;
    if (paged && !(std::max(w, h) <= side_limit)) return -1;
  }
  std::vector<Mask> masks(n);
  tbb::parallel_for(std::size_t{0}, n, [&](std::size_t i) {
    if (!stopRequested(progress)) masks[i] = chartMask(charts[i], texel_m);
  });
  if (stopRequested(progress)) return -1;
  std::vector<std::uint32_t> order(n);
  std::iota(order.begin(), order.end(), 0u);
  for (std::size_t i = 0; i < n; ++i) {
    if (std::min(masks[i].w, masks[i].h) > resolution - 2 * gutter) return -1;
    placements[i].width = masks[i].w;
    placements[i].height = masks[i].h;
  }
  std::sort(order.begin(), order.end(), [&](std::uint32_t a, std::uint32_t b) {
    const Mask &ma = masks[a], &mb = masks[b];
    const int la = std::max(ma.w, ma.h), lb = std::max(mb.w, mb.h);
    if (la != lb) return la > lb;
    const int sa = std::min(ma.w, ma.h), sb = std::min(mb.w, mb.h);
    if (sa != sb) return sa > sb;
    return a < b;
  });

  // Column heights per page: rows below are taken (or gutter). Border columns are closed.
  const int r = resolution;
  // A paged chart must end at or below the page's top gutter; a strip has no top.
  const int top_limit = paged ? r - gutter : std::numeric_limits<int>::max();
  std::vector<std::vector<int>> pages(1, std::vector<int>(static_cast<std::size_t>(r), gutter));
  std::vector<int> bottom, top;
  int used = gutter;
  std::size_t placed = 0;
  for (std::uint32_t id : order) {
    if (++placed % 64 == 0 && stopRequested(progress)) return -1;
    const Mask& m = masks[id];
    // Tiny charts gain nothing from half turns (their masks are nearly symmetric), and a
    // square one nothing from quarter turns either; they are most of a game level's charts.
    const int turn_count = std::max(m.w, m.h) <= 3 ? (m.w == m.h ? 1 : 2) : 4;
    int best_top = 0, best_x = -1, best_y = 0, best_turns = 0;
    std::size_t page = 0;
    for (;; ++page) {
      const bool fresh = page == pages.size();
      if (fresh) pages.emplace_back(static_cast<std::size_t>(r), gutter);
      const std::vector<int>& height = pages[page];
      best_top = top_limit == std::numeric_limits<int>::max() ? top_limit : top_limit + 1;
      for (int turns = 0; turns < turn_count; ++turns) {
        turnedProfile(m, turns, bottom, top);
        const int w = static_cast<int>(bottom.size());
        int top_max = 0;
        for (int t : top) top_max = std::max(top_max, t);
        for (int x = gutter; x + w <= r - gutter; ++x) {
          // The lowest y at which no column of the chart dips below the column heights;
          // give up on this x as soon as it cannot beat the best top found.
          const int limit = best_top - top_max;  // y must stay below this to improve
          int y = gutter;
          for (int c = 0; c < w && y < limit; ++c)
            y = std::max(y, height[static_cast<std::size_t>(x + c)] - bottom[static_cast<std::size_t>(c)]);
          if (y >= limit) continue;
          best_top = y + top_max;
          best_x = x;
          best_y = y;
          best_turns = turns;
        }
      }
      if (best_x >= 0) break;
      // A strip has one page; an empty page that cannot take the chart never will.
      if (!paged || fresh) return -1;
    }
    used = std::max(used, best_top);
    Placement& p = placements[id];
    p.x = best_x;
    p.y = best_y + static_cast<int>(page) * r;
    p.quarter_turns = best_turns;
    turnedProfile(m, best_turns, bottom, top);
    std::vector<int>& height = pages[page];
    const int w = static_cast<int>(bottom.size());
    for (int c = 0; c < w; ++c) {
      if (top[static_cast<std::size_t>(c)] < 0) continue;
      const int raised = best_y + top[static_cast<std::size_t>(c)] + gutter;
      for (int col = std::max(0, best_x + c - gutter); col <= std::min(r - 1, best_x + c + gutter); ++col)
        height[static_cast<std::size_t>(col)] = std::max(height[static_cast<std::size_t>(col)], raised);
    }
  }
  return paged ? static_cast<int>(pages.size()) : used;
}

}  // namespace

int packCharts(const std::vector<Chart>& charts, double texel_m, int resolution, int gutter,
               std::vector<Placement>& placements, const Progress* progress) {
  return packImpl(charts, texel_m, resolution, gutter, false, placements, progress);
}

int packChartsPaged(const std::vector<Chart>& charts, double texel_m, int resolution, int gutter,
                    std::vector<Placement>& placements, const Progress* progress) {
  return packImpl(charts, texel_m, resolution, gutter, true, placements, progress);
}

int chartMaskSide(const Chart& chart, double texel_m) {
  glm::dvec2 ext(0.0);
  for (const glm::dvec2& p : chart.uv) ext = glm::max(ext, p);
  const double side = std::floor(std::max(ext.x, ext.y) / texel_m + 0.5 + kMaskSlack) + 1.0;
  return side < double(kMaxPackSide) ? static_cast<int>(side) : static_cast<int>(kMaxPackSide);
}

void applyPlacement(Chart& chart, const Placement& placement, double texel_m) {
  const double w = placement.width, h = placement.height;
  for (glm::dvec2& p : chart.uv) {
    const glm::dvec2 q = p / texel_m + glm::dvec2(0.5);
    glm::dvec2 t;
    switch (placement.quarter_turns) {
      case 0: t = q; break;
      case 1: t = {h - q.y, q.x}; break;
      case 2: t = {w - q.x, h - q.y}; break;
      default: t = {q.y, w - q.x}; break;
    }
    p = t + glm::dvec2(placement.x, placement.y);
  }
}

}  // namespace lightlink::charts
