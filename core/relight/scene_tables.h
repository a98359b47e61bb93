// SceneTables: what every relight backend derives once from a precomputation and then only
// reads — the surfels' bounce gather (which caches each surfel reads, with what weight),
// which caches hold a value after the fill, each texel as a weighted sum of caches, the
// pull's areas and the surfels' materials. The relight pipeline (pipeline.h) and both
// backends' passes (CPU: cpu_passes.h, GPU: gpu/gpu_relight.h) read the same tables, so the
// two backends gather, pull and write texels from identical inputs.
//
// Built by SceneTables::build, which also checks that the precomputation and the link
// views agree (tree shape, cache counts, bands, mesh indices). The scene, accel,
// precomputation and link views must outlive the tables.
#pragma once

#include <cstdint>
#include <vector>

#include "core/common/status.h"
#include "core/links/links.h"
#include "core/precompute/precompute.h"
#include "core/relight/direct_points.h"
#include "core/relight/relight.h"
#include "core/rt/accel.h"
#include "core/scene/scene.h"

namespace lightlink::relight {

struct SceneTables {
  const scene::Scene& scene;
  const rt::Accel& accel;
  const precompute::Precomputation& p;
  links::LinksView lm_links, grid_links;

  std::vector<int> surfel_material;  // per surfel (tree order)
  // Bounce gather, CSR: surfel s reads caches gather_cache[gather_begin[s] .. gather_begin[s + 1])
  // with gather_weight, from the grid when gather_from_grid[s], else from the lightmap caches
  // (up to 4 bilinear texels, or 8 trilinear grid caches).
  std::vector<std::uint32_t> gather_begin, gather_cache;
  std::vector<float> gather_weight;
  std::vector<std::uint8_t> gather_from_grid;
  std::size_t surfels_without_gather = 0;
  // Some surfel gathers from the grid: every bounce pass must then light the grid too.
  bool grid_gathered = false;
  std::vector<std::uint8_t> lm_has_value, grid_has_value;  // valid, or filled from a valid neighbour
  // Every texel as a weighted sum of lightmap caches (its own, or its dilation sources
  // flattened), so writing texels is one parallel gather; texels without an entry are empty.
  detail::TexelMap texel_map;
  PullAreas pull;

  static Expected<SceneTables> build(const scene::Scene& scene, const rt::Accel& accel,
                                     const precompute::Precomputation& p, links::LinksView lightmap_links,
                                     links::LinksView grid_links);

  std::size_t surfelCount() const { return p.surfels.size(); }
  std::size_t nodeCount() const { return p.tree.nodeCount(); }

 private:
  SceneTables(const scene::Scene& s, const rt::Accel& a, const precompute::Precomputation& pc, links::LinksView lm,
              links::LinksView grid)
      : scene(s), accel(a), p(pc), lm_links(lm), grid_links(grid) {}
  void buildGather();
};

}  // namespace lightlink::relight
