#include <algorithm>
#include <limits>

#include "core/caches/caches.h"

namespace lightlink::caches {
namespace {

// Layered flood fill shared by the three plans. `known[i]` marks items that have a value;
// `wanted[i]` marks items to fill. Each layer fills the wanted items with at least one
// known neighbour, using only items known *before* the layer, so the plan does not depend
// on the order within a layer. `max_layers` bounds the spread (dilation passes).
template <typename ForNeighbours>
FillPlan layeredFill(std::vector<std::uint8_t> known, const std::vector<std::uint8_t>& wanted,
                     int max_layers, ForNeighbours&& for_neighbours) {
  FillPlan plan;
  plan.source_begin.push_back(0);
  std::vector<std::uint8_t> done(known.size(), 0);
  std::vector<std::uint32_t> layer, sources;
  for (int pass = 0; pass < max_layers; ++pass) {
    layer.clear();
    for (std::uint32_t i = 0; i < known.size(); ++i) {
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
// must not stay black: they take the nearest valid item in world space.
void fillUnreachable(FillPlan& plan, const std::vector<std::uint8_t>& valid,
                     const std::vector<std::uint8_t>& wanted, const std::vector<glm::vec3>& position) {
  std::vector<std::uint8_t> filled(valid.size(), 0);
  for (std::uint32_t t : plan.target) filled[t] = 1;
  std::vector<std::uint32_t> valid_ids;
  for (std::uint32_t i = 0; i < valid.size(); ++i)
    if (valid[i]) valid_ids.push_back(i);
  if (valid_ids.empty()) return;
  for (std::uint32_t i = 0; i < valid.size(); ++i) {
    if (!wanted[i] || filled[i]) continue;
    std::uint32_t best = valid_ids.front();
    float best_d = std::numeric_limits<float>::infinity();
    for (std::uint32_t j : valid_ids) {
      const glm::vec3 d = position[j] - position[i];
      const float d2 = glm::dot(d, d);
      if (d2 < best_d) {
        best_d = d2;
        best = j;
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
