#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>

#include "core/caches/caches.h"

namespace lightlink::caches {
namespace {

// Layered flood fill shared by the three plans. `known[i]` marks items that have a value;
// `wanted[i]` marks items to fill. Each layer fills the wanted items with at least one
// known neighbour, using only items known *before* the layer, so the plan does not depend
// on the order within a layer; a layer's targets are listed in index order. `max_layers`
// bounds the spread (dilation passes). Neighbourhoods are symmetric, so after the first
// layer only the neighbours of the last layer's targets can join the next one: each layer
// costs its frontier, not a scan of every item (a 4x direct layer has millions of texels
// and hundreds of layers across a wide invalid region).
template <typename ForNeighbours>
FillPlan layeredFill(std::vector<std::uint8_t> known, const std::vector<std::uint8_t>& wanted,
                     int max_layers, ForNeighbours&& for_neighbours) {
  FillPlan plan;
  plan.source_begin.push_back(0);
  std::vector<std::uint8_t> done(known.size(), 0), queued(known.size(), 0);
  std::vector<std::uint32_t> layer, sources, candidates;
  for (std::uint32_t i = 0; i < known.size(); ++i)
    if (wanted[i]) candidates.push_back(i);
  for (int pass = 0; pass < max_layers && !candidates.empty(); ++pass) {
    layer.clear();
    for (std::uint32_t i : candidates) {
      queued[i] = 0;
      if (!wanted[i] || done[i]) continue;
      sources.clear();
      for_neighbours(i, [&](std::uint32_t j) {
        if (known[j]) sources.push_back(j);
      });
      if (sources.empty()) continue;
      plan.target.push_back(i);
      plan.source.insert(plan.source.end(), sources.begin(), sources.end());
      plan.source_begin.push_back(static_cast<std::uint32_t>(plan.source.size()));
      layer.push_back(i);
    }
    if (layer.empty()) break;
    for (std::uint32_t i : layer) known[i] = done[i] = 1;
    candidates.clear();
    for (std::uint32_t i : layer)
      for_neighbours(i, [&](std::uint32_t j) {
        if (wanted[j] && !done[j] && !queued[j]) queued[j] = 1, candidates.push_back(j);
      });
    std::sort(candidates.begin(), candidates.end());
  }
  return plan;
}

// Texel neighbours in a fixed order (orthogonal first, then diagonal).
template <typename F>
void texelNeighbours(int w, int h, std::uint32_t texel, F&& f) {
  static constexpr int kOffsets[8][2] = {{-1, 0}, {1, 0}, {0, -1}, {0, 1}, {-1, -1}, {1, -1}, {-1, 1}, {1, 1}};
  const int x = static_cast<int>(texel % static_cast<std::uint32_t>(w));
  const int y = static_cast<int>(texel / static_cast<std::uint32_t>(w));
  for (const auto& o : kOffsets) {
    const int nx = x + o[0], ny = y + o[1];
    if (nx >= 0 && ny >= 0 && nx < w && ny < h) f(static_cast<std::uint32_t>(ny * w + nx));
  }
}

// Targets the flood cannot reach (a chart or room with no valid cache at all) still
// must not stay black: they take the nearest valid item in world space (the lowest index
// among equally near ones). A uniform grid over the valid items answers each query from the
// cells around it, shell by shell, stopping once no farther cell can hold a nearer item.
void fillUnreachable(FillPlan& plan, const std::vector<std::uint8_t>& valid,
                     const std::vector<std::uint8_t>& wanted, const std::vector<glm::vec3>& position) {
  std::vector<std::uint8_t> filled(valid.size(), 0);
  for (std::uint32_t t : plan.target) filled[t] = 1;
  std::vector<std::uint32_t> valid_ids, queries;
  for (std::uint32_t i = 0; i < valid.size(); ++i) {
    if (valid[i]) valid_ids.push_back(i);
    else if (wanted[i] && !filled[i]) queries.push_back(i);
  }
  if (valid_ids.empty() || queries.empty()) return;
  Aabb box;
  for (std::uint32_t j : valid_ids) box.grow(position[j]);
  const glm::vec3 extent = glm::max(box.max - box.min, glm::vec3(0.0f));
  const float longest = std::max({extent.x, extent.y, extent.z, 1e-6f});
  // About one valid item per cell along the longest axis's share, at most 2^21 cells.
  const double per_axis = std::cbrt(double(valid_ids.size()));
  float cell = std::max(longest / float(std::max(1.0, per_axis)), 1e-6f);
  glm::ivec3 dims;
  for (;;) {
    dims = glm::max(glm::ivec3(glm::floor(extent / cell)) + 1, glm::ivec3(1));
    if (std::int64_t(dims.x) * dims.y * dims.z <= (std::int64_t(1) << 21)) break;
    cell *= 1.25f;
  }
  auto cellIndex = [&](glm::ivec3 c) { return (std::size_t(c.z) * dims.y + c.y) * dims.x + c.x; };
  std::vector<std::uint32_t> begin(std::size_t(dims.x) * dims.y * dims.z + 1, 0), ids(valid_ids.size());
  auto cellOf = [&](const glm::vec3& p) {
    return glm::clamp(glm::ivec3(glm::floor((p - box.min) / cell)), glm::ivec3(0), dims - 1);
  };
  for (std::uint32_t j : valid_ids) ++begin[cellIndex(cellOf(position[j])) + 1];
  for (std::size_t c = 0; c + 1 < begin.size(); ++c) begin[c + 1] += begin[c];
  {
    std::vector<std::uint32_t> fill(begin.begin(), begin.end() - 1);
    for (std::uint32_t j : valid_ids) ids[fill[cellIndex(cellOf(position[j]))]++] = j;  // ascending per cell
  }
  for (std::uint32_t i : queries) {
    const glm::vec3 p = position[i];
    // The query's own cell, unclamped: a cell r shells away holds only points at least
    // (r - 1) cells away from p, wherever p lies.
    const glm::vec3 g = glm::floor((p - box.min) / cell);
    const glm::ivec3 q(glm::clamp(g, glm::vec3(-1e6f), glm::vec3(1e6f)));
    const int r_max = std::max({std::abs(q.x), std::abs(q.x - (dims.x - 1)), std::abs(q.y), std::abs(q.y - (dims.y - 1)),
                                std::abs(q.z), std::abs(q.z - (dims.z - 1))});
    std::uint32_t best = valid_ids.front();
    float best_d = std::numeric_limits<float>::infinity();
    for (int r = 0; r <= r_max; ++r) {
      if (std::isfinite(best_d)) {
        // Half a cell of slack for points the binning clamped onto the grid's last cell.
        const float reach = std::max(float(r) - 1.5f, 0.0f) * cell;
        if (reach * reach > best_d) break;
      }
      auto scan = [&](int x, int y, int z) {
        const std::size_t c = cellIndex({x, y, z});
        for (std::uint32_t k = begin[c]; k < begin[c + 1]; ++k) {
          const std::uint32_t j = ids[k];
          const glm::vec3 d = position[j] - p;
          const float d2 = glm::dot(d, d);
          if (d2 < best_d || (d2 == best_d && j < best)) {
            best_d = d2;
            best = j;
          }
        }
      };
      // The cells of shell r (Chebyshev distance r from q) inside the grid: whole rows on
      // its top, bottom and side faces, the two end cells of the rows in between.
      const glm::ivec3 lo = glm::max(q - r, glm::ivec3(0)), hi = glm::min(q + r, dims - 1);
      for (int z = lo.z; z <= hi.z; ++z)
        for (int y = lo.y; y <= hi.y; ++y) {
          if (std::abs(z - q.z) == r || std::abs(y - q.y) == r) {
            for (int x = lo.x; x <= hi.x; ++x) scan(x, y, z);
          } else {
            if (q.x - r >= 0 && q.x - r < dims.x) scan(q.x - r, y, z);
            if (r > 0 && q.x + r >= 0 && q.x + r < dims.x) scan(q.x + r, y, z);
          }
        }
    }
    plan.target.push_back(i);
    plan.source.push_back(best);
    plan.source_begin.push_back(static_cast<std::uint32_t>(plan.source.size()));
    ++plan.unreachable;
  }
}

}  // namespace

FillPlan planLightmapFill(const LightmapCaches& caches) {
  // Work in cache indices; neighbours are found through the texel grid.
  const std::size_t n = caches.size();
  std::vector<std::uint8_t> wanted(n);
  for (std::size_t i = 0; i < n; ++i) wanted[i] = caches.valid[i] ? 0 : 1;
  FillPlan plan = layeredFill(caches.valid, wanted, std::numeric_limits<int>::max(),
                              [&](std::uint32_t i, auto&& emit) {
                                texelNeighbours(caches.width, caches.height, caches.texel[i], [&](std::uint32_t t) {
                                  const std::int32_t c = caches.cache_of_texel[t];
                                  if (c >= 0) emit(static_cast<std::uint32_t>(c));
                                });
                              });
  fillUnreachable(plan, caches.valid, wanted, caches.position);
  return plan;
}

FillPlan planGridFill(const GridCaches& grid) {
  const std::size_t n = grid.size();
  std::vector<std::uint8_t> wanted(n);
  for (std::size_t i = 0; i < n; ++i) wanted[i] = grid.valid[i] ? 0 : 1;
  const glm::ivec3 d = grid.dims;
  FillPlan plan = layeredFill(grid.valid, wanted, std::numeric_limits<int>::max(),
                              [&](std::uint32_t i, auto&& emit) {
                                const int x = static_cast<int>(i % std::uint32_t(d.x));
                                const int y = static_cast<int>((i / std::uint32_t(d.x)) % std::uint32_t(d.y));
                                const int z = static_cast<int>(i / (std::uint32_t(d.x) * std::uint32_t(d.y)));
                                for (int dz = -1; dz <= 1; ++dz)
                                  for (int dy = -1; dy <= 1; ++dy)
                                    for (int dx = -1; dx <= 1; ++dx) {
                                      if (dx == 0 && dy == 0 && dz == 0) continue;
                                      const int nx = x + dx, ny = y + dy, nz = z + dz;
                                      if (nx < 0 || ny < 0 || nz < 0 || nx >= d.x || ny >= d.y || nz >= d.z) continue;
                                      emit(static_cast<std::uint32_t>((nz * d.y + ny) * d.x + nx));
                                    }
                              });
  fillUnreachable(plan, grid.valid, wanted, grid.position);
  return plan;
}

FillPlan planDilation(const LightmapCaches& caches, int passes) {
  const std::size_t texels = caches.cache_of_texel.size();
  std::vector<std::uint8_t> known(texels), wanted(texels);
  for (std::size_t t = 0; t < texels; ++t) {
    known[t] = caches.cache_of_texel[t] >= 0 ? 1 : 0;
    wanted[t] = known[t] ? 0 : 1;
  }
  return layeredFill(std::move(known), wanted, std::max(0, passes), [&](std::uint32_t t, auto&& emit) {
    texelNeighbours(caches.width, caches.height, t, emit);
  });
}

}  // namespace lightlink::caches
