#include "core/relight/scene_tables.h"

#include <algorithm>
#include <cmath>

#include "core/sh/sh.h"

namespace lightlink::relight {

Expected<SceneTables> SceneTables::build(const scene::Scene& scene, const rt::Accel& accel,
                                         const precompute::Precomputation& p, links::LinksView lm,
                                         links::LinksView grid) {
  const std::size_t ns = p.surfels.size();
  if (p.tree.surfelCount() != ns || p.tree.nodeCount() != (ns ? 2 * ns - 1 : 0))
    return invalidInput("relight: tree ({} surfels, {} nodes) does not match {} surfels", p.tree.surfelCount(),
                        p.tree.nodeCount(), ns);
  if (lm.cacheCount() != p.lightmap.size())
    return invalidInput("relight: lightmap links cover {} caches, the precomputation has {}", lm.cacheCount(),
                        p.lightmap.size());
  if (p.has_grid && grid.cacheCount() != p.grid.size())
    return invalidInput("relight: grid links cover {} caches, the grid has {}", grid.cacheCount(), p.grid.size());
  if (lm.bands < 1 || lm.bands > sh::kMaxBands) return invalidInput("relight: link bands {} not in 1..4", lm.bands);
  for (std::size_t i = 0; i < ns; ++i)
    if (p.surfels.mesh[i] >= scene.meshes.size())
      return invalidInput("relight: surfel {} names mesh {} of a scene with {} meshes", i, p.surfels.mesh[i],
                          scene.meshes.size());
  // The AVX2 runtime kernel gathers with 32-bit offsets 4 * node.
  if (p.tree.nodeCount() >= (std::size_t(1) << 29))
    return invalidInput("relight: {} tree nodes exceed 2^29", p.tree.nodeCount());
  auto pull = pullAreas(p);
  if (!pull) return pull.status();
  SceneTables t(scene, accel, p, lm, grid);
  t.pull = std::move(pull).value();
  t.surfel_material.resize(ns);
  for (std::size_t i = 0; i < ns; ++i) t.surfel_material[i] = scene.meshes[p.surfels.mesh[i]].material;
  t.buildGather();
  t.texel_map = detail::buildTexelMap(p.lightmap.cache_of_texel, t.lm_has_value, p.dilation);
  return t;
}

void SceneTables::buildGather() {
  // Which caches hold a value after the fill: valid ones and fill targets with sources.
  lm_has_value = detail::hasValue(p.lightmap.valid, p.lightmap_fill);
  if (p.has_grid) grid_has_value = detail::hasValue(p.grid.valid, p.grid_fill);

  const std::size_t ns = p.surfels.size();
  const int w = p.lightmap.width, h = p.lightmap.height;
  gather_begin.assign(1, 0);
  gather_from_grid.assign(ns, 0);
  surfels_without_gather = 0;
  auto texelCache = [&](int x, int y) -> std::int32_t {
    if (x < 0 || y < 0 || x >= w || y >= h) return -1;
    const std::int32_t c = p.lightmap.cache_of_texel[std::size_t(y) * w + x];
    return c >= 0 && lm_has_value[c] ? c : -1;
  };
  for (std::size_t s = 0; s < ns; ++s) {
    const glm::vec2 uv = p.surfels.lightmap_uv[s];
    std::size_t added = 0;
    if (w > 0 && uv.x >= 0.0f && uv.y >= 0.0f) {
      // Texel (x, y) covers [x, x + 1) in uv * resolution, its centre is at x + 0.5.
      const float fx = uv.x * w - 0.5f, fy = uv.y * h - 0.5f;
      const int x0 = int(std::floor(fx)), y0 = int(std::floor(fy));
      const float tx = fx - x0, ty = fy - y0;
      float wsum = 0.0f;
      const std::size_t start = gather_cache.size();
      for (int dy = 0; dy < 2; ++dy)
        for (int dx = 0; dx < 2; ++dx) {
          const std::int32_t c = texelCache(x0 + dx, y0 + dy);
          const float wt = (dx ? tx : 1.0f - tx) * (dy ? ty : 1.0f - ty);
          if (c < 0 || wt <= 0.0f) continue;
          gather_cache.push_back(std::uint32_t(c));
          gather_weight.push_back(wt);
          wsum += wt;
        }
      if (wsum > 0.0f) {
        for (std::size_t k = start; k < gather_cache.size(); ++k) gather_weight[k] /= wsum;
        added = gather_cache.size() - start;
      } else {
        // Nearest texel with a value within 2 texels (a surfel in a chart's gutter corner).
        float best = 1e30f;
        std::int32_t best_c = -1;
        const int cx = int(std::floor(uv.x * w)), cy = int(std::floor(uv.y * h));
        for (int dy = -2; dy <= 2; ++dy)
          for (int dx = -2; dx <= 2; ++dx) {
            const std::int32_t c = texelCache(cx + dx, cy + dy);
            const float d = float(dx * dx + dy * dy);
            if (c >= 0 && d < best) best = d, best_c = c;
          }
        if (best_c >= 0) {
          gather_cache.push_back(std::uint32_t(best_c));
          gather_weight.push_back(1.0f);
          added = 1;
        }
      }
    }
    if (added == 0 && p.has_grid && p.grid.spacing_m > 0.0f) {
      // Trilinear over the grid caches that hold a value.
      const glm::vec3 g = (p.surfels.position[s] - p.grid.origin) / p.grid.spacing_m;
      const glm::ivec3 i0 = glm::clamp(glm::ivec3(glm::floor(g)), glm::ivec3(0), glm::max(p.grid.dims - 2, 0));
      const glm::vec3 t = glm::clamp(g - glm::vec3(i0), 0.0f, 1.0f);
      float wsum = 0.0f;
      const std::size_t start = gather_cache.size();
      for (int c = 0; c < 8; ++c) {
        const glm::ivec3 o(c & 1, (c >> 1) & 1, (c >> 2) & 1);
        const glm::ivec3 q = glm::min(i0 + o, p.grid.dims - 1);
        const std::size_t idx = (std::size_t(q.z) * p.grid.dims.y + q.y) * p.grid.dims.x + q.x;
        const float wt = (o.x ? t.x : 1 - t.x) * (o.y ? t.y : 1 - t.y) * (o.z ? t.z : 1 - t.z);
        if (!grid_has_value[idx] || wt <= 0.0f) continue;
        gather_cache.push_back(std::uint32_t(idx));
        gather_weight.push_back(wt);
        wsum += wt;
      }
      if (wsum > 0.0f) {
        for (std::size_t k = start; k < gather_cache.size(); ++k) gather_weight[k] /= wsum;
        added = gather_cache.size() - start;
        gather_from_grid[s] = 1;
      } else {
        gather_cache.resize(start), gather_weight.resize(start);
      }
    }
    if (added == 0) ++surfels_without_gather;
    gather_begin.push_back(std::uint32_t(gather_cache.size()));
  }
  grid_gathered = std::find(gather_from_grid.begin(), gather_from_grid.end(), std::uint8_t(1)) != gather_from_grid.end();
}

}  // namespace lightlink::relight
