#include "core/precompute/precompute.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cctype>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <optional>
#include <new>
#include <sstream>

#include <unistd.h>

#include <fmt/format.h>

#include "core/caches/cutout_texels.h"
#include "core/common/memory.h"
#include "core/links/surfel_locator.h"
#include "core/rt/accel.h"
#include "core/scene/load.h"
#include "core/scene/obj_files.h"
#include "core/scene/lighting_images.h"

namespace lightlink::precompute {
namespace {

using Clock = std::chrono::steady_clock;

double secondsSince(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

template <typename T, typename A>
std::size_t bytesOf(const std::vector<T, A>& v) {
  return v.size() * sizeof(T);
}

// The one list of the small arrays an artifact holds (copied on load), by section name.
// Works on const (save) and mutable (load) precomputations alike.
template <typename P, typename V>
void visitSmallArrays(P& p, V&& v) {
  v("surfel.position", p.surfels.position);
  v("surfel.normal", p.surfels.normal);
  v("surfel.area", p.surfels.area);
  v("surfel.albedo", p.surfels.albedo);
  v("surfel.emission", p.surfels.emission);
  v("surfel.lightmap_uv", p.surfels.lightmap_uv);
  v("surfel.mesh", p.surfels.mesh);
  v("surfel.triangle", p.surfels.triangle);
  v("surfel.barycentric", p.surfels.barycentric);
  v("surfel.seen", p.surfel_seen);
  v("tree.left", p.tree.left);
  v("tree.right", p.tree.right);
  v("tree.parent", p.tree.parent);
  v("tree.begin", p.tree.begin);
  v("tree.end", p.tree.end);
  v("tree.depth", p.tree.depth);
  v("tree.area", p.tree.area);
  v("tree.bounds_min", p.tree.bounds_min);
  v("tree.bounds_max", p.tree.bounds_max);
  v("tree.centroid", p.tree.centroid);
  v("tree.mean_normal", p.tree.mean_normal);
  v("tree.level_begin", p.tree.level_begin);
  v("tree.leaf_of_surfel", p.tree.leaf_of_surfel);
  v("tree.original_index", p.tree.original_index);
  v("lm.position", p.lightmap.position);
  v("lm.normal", p.lightmap.normal);
  v("lm.texel", p.lightmap.texel);
  v("lm.mesh", p.lightmap.mesh);
  v("lm.triangle", p.lightmap.triangle);
  v("lm.valid", p.lightmap.valid);
  v("lm.pushed", p.lightmap.pushed);
  v("lm.cache_of_texel", p.lightmap.cache_of_texel);
  v("grid.position", p.grid.position);
  v("grid.valid", p.grid.valid);
  v("dt.position", p.direct_texels.position);
  v("dt.normal", p.direct_texels.normal);
  v("dt.texel", p.direct_texels.texel);
  v("dt.mesh", p.direct_texels.mesh);
  v("dt.triangle", p.direct_texels.triangle);
  v("dt.valid", p.direct_texels.valid);
  v("dt.pushed", p.direct_texels.pushed);
  v("dt.cache_of_texel", p.direct_texels.cache_of_texel);
  for (auto* plan : {&p.lightmap_fill, &p.grid_fill, &p.dilation, &p.direct_fill, &p.direct_dilation}) {
    const char* prefix = plan == &p.lightmap_fill ? "lmfill"
                         : plan == &p.grid_fill   ? "gridfill"
                         : plan == &p.dilation    ? "dilate"
                         : plan == &p.direct_fill ? "dtfill"
                                                  : "dtdilate";
    v(fmt::format("{}.target", prefix), plan->target);
    v(fmt::format("{}.begin", prefix), plan->source_begin);
    v(fmt::format("{}.source", prefix), plan->source);
  }
}

// The big link arrays, by section name (zero-copy on load).
template <typename L, typename V>
void visitLinkArrays(const char* prefix, L& links, V&& v) {
  v(fmt::format("{}.offsets", prefix), links.offsets);
  v(fmt::format("{}.node", prefix), links.node);
  v(fmt::format("{}.coeffs", prefix), links.coeffs);
  v(fmt::format("{}.direction", prefix), links.direction);
  v(fmt::format("{}.solid_angle", prefix), links.solid_angle);
  v(fmt::format("{}.sky", prefix), links.sky);
}

nlohmann::ordered_json linkStatsJson(const links::Links& l) {
  nlohmann::ordered_json j;
  j["caches"] = l.cacheCount();
  j["links"] = l.linkCount();
  j["mean_links_per_cache"] = l.cacheCount() ? double(l.linkCount()) / double(l.cacheCount()) : 0.0;
  j["rays"] = l.stats.rays;
  j["front_hits"] = l.stats.front_hits;
  j["back_hits"] = l.stats.back_hits;
  j["escaped"] = l.stats.escaped;
  j["unowned"] = l.stats.unowned;
  j["seconds"] = l.stats.seconds;
  j["rays_per_second"] = l.stats.seconds > 0 ? double(l.stats.rays) / l.stats.seconds : 0.0;
  // Where the time went, as shares of the phases' sum (their ticks have no fixed unit), and
  // link generation's own work per unit of Embree time: benchmark builds only.
  if (links::kPhaseProbes) {
    const double total = double(l.stats.totalPhaseTicks());
    nlohmann::ordered_json share = nlohmann::ordered_json::object();
    for (int k = 0; k < links::kLinkPhases; ++k)
      share[links::kLinkPhaseNames[k]] = total > 0 ? double(l.stats.phase_ticks[k]) / total : 0.0;
    j["phase_share"] = share;
    const double trace = double(l.stats.phase_ticks[links::kPhaseTrace]);
    j["own_work_per_trace"] = trace > 0 ? (total - trace) / trace : 0.0;
  }
  j["bytes_per_link_projected"] = l.bytesPerLinkProjected();
  j["bytes_per_link_runtime"] = links::Links::bytesPerLinkRuntime();
  return j;
}

}  // namespace

Status PrecomputeOptions::validate() const {
  if (surfels < 1 || surfels > (1u << 24)) return invalidInput("--surfels {} is out of range (1..16777216)", surfels);
  if (links < 1 || links > 65536) return invalidInput("--links {} is out of range (1..65536)", links);
  if (bands < 1 || bands > 4) return invalidInput("--bands {} is out of range (1..4)", bands);
  if (rays < 1 || rays > (1 << 20)) return invalidInput("--rays {} is out of range (1..1048576)", rays);
  if (!(grid_spacing_m >= 0.0f) || !std::isfinite(grid_spacing_m))
    return invalidInput("--grid-spacing {} must be a finite number >= 0 (0 = derive)", grid_spacing_m);
  if (grid_resolution < 2 || grid_resolution > 1024)
    return invalidInput("grid resolution {} is out of range (2..1024)", grid_resolution);
  if (texel_size_m && !(*texel_size_m > 0.0f && std::isfinite(*texel_size_m)))
    return invalidInput("--texel-size {} must be a finite number > 0", *texel_size_m);
  if (texel_budget > (std::uint64_t(1) << 28))
    return invalidInput("texel budget {} is out of range (0..268435456)", texel_budget);
  if (max_pages < 0 || max_pages > 1024)
    return invalidInput("--max-pages {} is out of range (0..1024, 0 = as many as needed)", max_pages);
  if (max_atlas < 16 || max_atlas > charts::kMaxAtlasResolution)
    return invalidInput("--max-atlas {} is out of range (16..{})", max_atlas, charts::kMaxAtlasResolution);
  if (lightmap_resolution && (*lightmap_resolution < 1 || *lightmap_resolution > charts::kMaxAtlasResolution))
    return invalidInput("lightmap resolution {} is out of range (1..{})", *lightmap_resolution,
                        charts::kMaxAtlasResolution);
  if (validity_rays < 1 || validity_rays > 65536)
    return invalidInput("validity rays {} is out of range (1..65536)", validity_rays);
  if (direct_scale < 1 || direct_scale > kMaxDirectScale)
    return invalidInput("--direct-scale {} is out of range (1..{})", direct_scale, kMaxDirectScale);
  if (shard && (shard->count < 1 || shard->count > kMaxShards || shard->index < 0 || shard->index >= shard->count))
    return invalidInput("--shard {}/{} is out of range (I/N with 0 <= I < N <= {})", shard->index, shard->count,
                        kMaxShards);
  return {};
}

Expected<ShardSpec> parseShard(std::string_view text) {
  // Digits only, no sign or blank: a job script's typo must not quietly pick another shard.
  auto number = [](std::string_view digits, int& out) {
    if (digits.empty() || digits.size() > 9) return false;
    out = 0;
    for (const char c : digits) {
      if (c < '0' || c > '9') return false;
      out = out * 10 + (c - '0');
    }
    return true;
  };
  const auto slash = text.find('/');
  ShardSpec s;
  if (slash == std::string_view::npos || !number(text.substr(0, slash), s.index) ||
      !number(text.substr(slash + 1), s.count))
    return invalidInput("--shard '{}' must be I/N (shard I of N, counted from 0), e.g. 0/4", text);
  if (s.count < 1 || s.count > kMaxShards || s.index >= s.count)
    return invalidInput("--shard '{}': I must be below N and N at most {} (shards are counted from 0)", text,
                        kMaxShards);
  return s;
}

CacheRange shardRange(std::size_t total, const ShardSpec& s) {
  // floor(total * i / count) without the product overflowing: total = q * count + r.
  const std::size_t count = static_cast<std::size_t>(s.count), q = total / count, r = total % count;
  const auto at = [&](int i) { return q * std::size_t(i) + r * std::size_t(i) / count; };
  return {at(s.index), at(s.index + 1)};
}

Expected<PrecomputeOptions> preset(std::string_view name) {
  // Derived from the accuracy study's Pareto front (docs/quality.md has the rule and the
  // measured error and cost of each). Fewer surfels with more links beat the reverse at equal
  // relight time; 4 bands add nothing to irradiance (the clamped cosine's band-3 factor is 0).
  PrecomputeOptions o;
  if (name == "draft") {
    o.surfels = 4096;
    o.links = 64;
    o.rays = 512;
    o.texel_budget = 16384;
  } else if (name == "medium") {
    o.surfels = 32768;
    o.links = 128;
    o.rays = 1024;
    o.texel_budget = 32768;
    o.direct_scale = 2;
  } else if (name == "high") {
    o.surfels = 16384;
    o.links = 256;
    o.bands = 3;
    o.rays = 2048;
    o.texel_budget = 131072;
    o.direct_scale = 2;
  } else {
    return invalidInput("--preset '{}' must be draft, medium or high", name);
  }
  return o;
}

std::string PrecomputeOptions::canonical() const {
  return fmt::format(
      "surfels={};links={};bands={};rays={};builder={};grid={};grid_spacing={:a};grid_resolution={};"
      "texel_size={};texel_budget={};max_atlas={};max_pages={};lightmap_resolution={};target_resolution={};uv={};"
      "validity_rays={};direct_scale={};seed={};generator={}",
      surfels, links, bands, rays, hierarchy::builderName(builder),
      static_cast<int>(grid), grid_spacing_m, grid_resolution,
      texel_size_m ? fmt::format("{:a}", *texel_size_m) : "auto", texel_budget, max_atlas, max_pages,
      lightmap_resolution ? std::to_string(*lightmap_resolution) : "auto", target_resolution,
      uv_mode == charts::UvMode::kAuto ? "auto" : uv_mode == charts::UvMode::kKeep ? "keep" : "generate", validity_rays,
      direct_scale, seed,
      kGeneratorRevision) +
         (surfaces.empty() ? std::string() : ";surfaces=" + surfaces.canonical());
}

std::uint64_t linkBytesEstimate(std::uint64_t caches, int max_links, int bands) {
  // Per link: the projected form (node + SH coefficients) and the runtime form (node,
  // direction, solid angle), as links::Links holds them.
  const std::uint64_t per_link =
      links::Links::bytesPerLinkRuntime() + sizeof(std::uint16_t) * std::uint64_t(bands) * std::uint64_t(bands);
  return caches * std::uint64_t(std::max(max_links, 0)) * per_link;
}

std::uint64_t effectiveLinkBudget(const PrecomputeLimits& limits) {
  if (limits.max_link_bytes != 0) return limits.max_link_bytes;
  const long pages = ::sysconf(_SC_PHYS_PAGES), page = ::sysconf(_SC_PAGESIZE);
  if (pages <= 0 || page <= 0) return std::uint64_t(8) << 30;  // unknown: 8 GiB
  return std::uint64_t(pages) * std::uint64_t(page) / 2;
}

Expected<charts::UnwrapResult> unwrapFor(scene::Scene& scene, const PrecomputeOptions& options,
                                         const Progress* progress) {
  charts::UnwrapOptions u;
  u.texel_size_m = options.texel_size_m;
  u.texel_budget = options.texel_budget;
  u.max_atlas = options.max_atlas;
  u.max_pages = options.max_pages;
  u.resolution = options.lightmap_resolution;
  u.target_resolution = options.target_resolution;
  u.uv_mode = options.uv_mode;
  u.max_texels = options.limits.max_texels;
  u.progress = progress;
  return charts::unwrap(scene, u);
}

Expected<Precomputation> run(scene::Scene& scene, const PrecomputeOptions& options, Progress* progress) {
  if (Status s = options.validate(); !s) return s;
  // Link generation's freed output blocks are reused within the run, and released after it.
  const HugeBlockCacheScope huge_blocks;
  NullProgress null_progress;
  Progress& sink = progress ? *progress : null_progress;
  Precomputation p;
  p.options = options;
  // Stages that report their own progress (links) get no begin/end of their own here.
  // Running out of memory in a stage (in any TBB worker: TBB rethrows here) is an error
  // naming the stage, not an abort; so is a cancellation noticed at the stage's end.
  auto stage = [&](const char* name, auto&& body, bool self_reporting = false) -> Status {
    if (sink.cancelled()) return cancelled("precompute cancelled before {}", name);
    const auto t0 = Clock::now();
    if (!self_reporting) sink.begin(name, 0);
    Status s;
    try {
      s = body();
    } catch (const std::bad_alloc&) {
      s = resourceExhausted("out of memory while computing {} (lower the resolution, surfels or links)", name);
    }
    if (!self_reporting) sink.end();
    p.timings.push_back({name, secondsSince(t0)});
    if (s.isOk() && sink.cancelled()) return cancelled("precompute cancelled during {}", name);
    return s;
  };

  Status s = stage("unwrap", [&]() -> Status {
    auto r = unwrapFor(scene, options, &sink);
    if (!r) return r.status();
    p.atlas = std::move(r->atlas);
    p.warnings = r->report.warnings;
    p.probe_lit_names = r->report.probe_lit;
    p.notes.push_back(p.atlas.generated
                          ? fmt::format("lightmap UVs generated: {} charts on {} page{} of {}x{} at {:.4g} m/texel",
                                        p.atlas.chart_count, p.atlas.pages, p.atlas.pages == 1 ? "" : "s",
                                        p.atlas.resolution, p.atlas.resolution, p.atlas.texel_size_m)
                          : "lightmap UVs: every static mesh has TEXCOORD_1, kept");
    if (!p.atlas.probe_lit.empty())
      p.notes.push_back(fmt::format("{} static meshes lit from the irradiance volume (too small for the lightmap "
                                    "or marked lightmap: false)",
                                    p.atlas.probe_lit.size()));
    return {};
  });
  if (!s) return s;

  s = stage("surfels", [&]() -> Status {
    auto r = surfels::placeSurfels(
        scene, {.count = options.surfels, .seed = static_cast<std::uint32_t>(options.seed), .progress = &sink});
    if (!r) return r.status();
    p.surfels = std::move(r).value();
    if (p.surfels.empty()) return invalidInput("{}: the scene has no static surface area to place surfels on",
                                               scene.source_path);
    return {};
  });
  if (!s) return s;

  s = stage("hierarchy", [&]() -> Status {
    auto r = hierarchy::buildTree(p.surfels, {.builder = options.builder, .progress = &sink});
    if (!r) return r.status();
    p.tree = std::move(r).value();
    return {};
  });
  if (!s) return s;

  std::optional<rt::Accel> accel;
  s = stage("bvh", [&]() -> Status {
    auto r = rt::Accel::build(scene);
    if (!r) return r.status();
    accel.emplace(std::move(r).value());
    return {};
  });
  if (!s) return s;

  const caches::ValidityOptions validity{.rays = options.validity_rays, .progress = &sink};
  s = stage("caches", [&]() -> Status {
    auto lm = caches::placeLightmapCaches(
        scene, *accel, {.resolution = p.atlas.resolution, .pages = p.atlas.pages, .validity = validity});
    if (!lm) return lm.status();
    p.lightmap = std::move(lm).value();
    if (const std::size_t cut = caches::invalidateCutoutTexels(scene, p.lightmap); cut > 0)
      p.notes.push_back(fmt::format("{} lightmap texels over alpha cut-outs left invalid (filled from their neighbours)", cut));
    bool dynamic = false;
    Aabb probe_lit_bounds;
    for (const auto& m : scene.meshes) dynamic |= !m.is_static;
    for (std::uint32_t m : p.atlas.probe_lit)
      for (const glm::vec3& v : scene.meshes[m].positions) probe_lit_bounds.grow(v);
    const bool probe_lit = !p.atlas.probe_lit.empty();
    p.has_grid = options.grid == GridMode::kOn || (options.grid == GridMode::kAuto && (dynamic || probe_lit));
    if (options.grid == GridMode::kAuto)
      p.notes.push_back(dynamic     ? "grid caches: the scene has dynamic meshes"
                        : probe_lit ? "grid caches: around the probe-lit static meshes"
                                    : "grid caches skipped: no dynamic or probe-lit meshes and no grid requested");
    if (p.has_grid) {
      caches::GridCacheOptions g;
      g.spacing_m = options.grid_spacing_m;
      g.resolution = options.grid_resolution;
      g.validity = validity;
      // Only probe-lit objects need it: a volume around them (a grid spacing of margin at
      // the scene's resolution), not the whole level.
      if (!dynamic && probe_lit && options.grid != GridMode::kOn) {
        const glm::vec3 ext = scene.bounds.max - scene.bounds.min;
        const float spacing = options.grid_spacing_m > 0.0f
                                  ? options.grid_spacing_m
                                  : std::max({ext.x, ext.y, ext.z}) / float(options.grid_resolution - 1);
        g.spacing_m = spacing;
        g.volume = probe_lit_bounds;
        g.volume.min -= glm::vec3(spacing);
        g.volume.max += glm::vec3(spacing);
      }
      auto grid = caches::placeGridCaches(scene, *accel, g);
      if (!grid) return grid.status();
      p.grid = std::move(grid).value();
    }
    p.lightmap_fill = caches::planLightmapFill(p.lightmap);
    p.grid_fill = p.has_grid ? caches::planGridFill(p.grid) : caches::FillPlan{};
    p.dilation = caches::planDilation(p.lightmap, std::max(1, p.atlas.gutter_texels));
    return {};
  });
  if (!s) return s;

  // The direct layer: the same charts rasterised direct_scale times finer, placed and
  // validity-tested as caches are (a texel inside geometry would read a false shadow).
  if (options.direct_scale > 1 && p.lightmap.width > 0) {
    int scale = options.direct_scale;
    auto fits = [&](int k) {
      const std::uint64_t w = std::uint64_t(p.lightmap.width) * k, h = std::uint64_t(p.lightmap.height) * k;
      return w <= std::uint64_t(charts::kMaxAtlasResolution) && h <= std::uint64_t(charts::kMaxAtlasResolution) &&
             w * h <= options.limits.max_texels;
    };
    while (scale > 1 && !fits(scale)) --scale;
    if (scale != options.direct_scale)
      p.warnings.push_back(fmt::format(
          "direct scale {} lowered to {}: a {}x{} direct layer would exceed the texel limit (raise --texel-size "
          "or lower --direct-scale)",
          options.direct_scale, scale, std::uint64_t(p.lightmap.width) * options.direct_scale,
          std::uint64_t(p.lightmap.height) * options.direct_scale));
    if (scale > 1) {
      s = stage("direct_texels", [&]() -> Status {
        // A quarter of the caches' validity rays and no footprint search: a direct texel only
        // needs to know whether it lies inside geometry (no links read its hemisphere), a
        // failed one is filled from its neighbours, and there are K^2 as many.
        caches::ValidityOptions dv = validity;
        dv.rays = std::max(8, options.validity_rays / 4);
        auto dt = caches::placeLightmapCaches(
            scene, *accel,
            {.resolution = p.atlas.resolution * scale, .pages = p.atlas.pages, .validity = dv,
             .footprint_search = false});
        if (!dt) return dt.status();
        p.direct_texels = std::move(dt).value();
        p.direct_fill = caches::planLightmapFill(p.direct_texels);
        p.direct_dilation = caches::planDilation(p.direct_texels, std::max(1, p.atlas.gutter_texels * scale));
        p.notes.push_back(fmt::format("direct layer: {}x{} texels ({} per lightmap texel along each axis), {} placed",
                                      p.direct_texels.width, p.direct_texels.height, scale, p.direct_texels.size()));
        return {};
      });
      if (!s) return s;
    }
  } else if (options.direct_scale > 1) {
    p.notes.push_back("direct layer skipped: no lightmap texels");
  }

  // Which surfel owns a hit: built once for the lightmap and the grid caches (a per-scene
  // structure, as the BVH is, and timed as its own stage).
  std::optional<links::SurfelLocator> owners;
  s = stage("owners", [&]() -> Status {
    owners.emplace(p.surfels, scene);
    return {};
  });
  if (!s) return s;

  // A shard links its range of the caches (lightmap caches first, then grid caches, as one
  // sequence); everything above is the same on every shard.
  const std::size_t lm_total = p.lightmap.size(), grid_total = p.has_grid ? p.grid.size() : 0;
  p.lightmap_linked = {0, lm_total};
  p.grid_linked = {0, grid_total};
  if (options.shard) {
    const CacheRange all = shardRange(lm_total + grid_total, *options.shard);
    p.lightmap_linked = {std::min(all.begin, lm_total), std::min(all.end, lm_total)};
    p.grid_linked = {std::max(all.begin, lm_total) - lm_total, std::max(all.end, lm_total) - lm_total};
  }
  const std::size_t lm_count = p.lightmap_linked.end - p.lightmap_linked.begin;
  const std::size_t grid_count = p.grid_linked.end - p.grid_linked.begin;

  // Links are the bulk of the memory: caches x links x bytes, checked before any is made.
  const std::uint64_t link_bytes = linkBytesEstimate(lm_count + grid_count, options.links, options.bands);
  if (const std::uint64_t budget = effectiveLinkBudget(options.limits); link_bytes > budget)
    return resourceExhausted("links: {} caches x {} links x {} bands need up to {:.1f} MiB, above the limit of {:.1f} "
                             "MiB (max_link_bytes); lower the links, bands or lightmap resolution",
                             lm_count + grid_count, options.links, options.bands,
                             double(link_bytes) / double(1 << 20), double(budget) / double(1 << 20));

  const links::LinkOptions link_options = options.linkOptions();
  s = stage("links", [&]() -> Status {
    links::LinkOptions lm_options = link_options;
    lm_options.progress_label = "links lightmap";
    lm_options.first_cache = p.lightmap_linked.begin;
    const std::span<const glm::vec3> lm_position(p.lightmap.position), lm_normal(p.lightmap.normal);
    auto lm = links::generateLinks(
        scene, *accel, *owners, p.tree,
        {lm_position.subspan(p.lightmap_linked.begin, lm_count), lm_normal.subspan(p.lightmap_linked.begin, lm_count)},
        lm_options, &sink);
    if (!lm) return lm.status();
    p.lightmap_links = std::move(lm).value();
    if (p.has_grid) {
      const std::vector<glm::vec3> sphere(grid_count, glm::vec3(0.0f));
      links::LinkOptions grid_options = link_options;
      grid_options.progress_label = "links grid";
      grid_options.first_cache = p.grid_linked.begin;
      const std::span<const glm::vec3> grid_position(p.grid.position);
      auto g = links::generateLinks(scene, *accel, *owners, p.tree,
                                    {grid_position.subspan(p.grid_linked.begin, grid_count), sphere}, grid_options,
                                    &sink);
      if (!g) return g.status();
      p.grid_links = std::move(g).value();
    }
    // A surfel is seen when either set of caches sees it; the per-set flags go.
    p.surfel_seen = std::move(p.lightmap_links.seen);
    for (std::size_t i = 0; i < p.grid_links.seen.size(); ++i) p.surfel_seen[i] |= p.grid_links.seen[i];
    p.lightmap_links.seen = {};
    p.grid_links.seen = {};
    return {};
  }, /*self_reporting=*/true);
  if (!s) return s;
  return p;
}

nlohmann::ordered_json Precomputation::report() const {
  nlohmann::ordered_json j;
  j["options"] = options.canonical();
  j["counts"] = {{"surfels", surfels.size()},
                 {"tree_nodes", tree.nodeCount()},
                 {"tree_levels", tree.levelCount()},
                 {"lightmap_resolution", atlas.resolution},
                 {"lightmap_pages", atlas.pages},
                 {"lightmap_charts", atlas.chart_count},
                 {"texel_size_m", atlas.texel_size_m},
                 {"probe_lit_meshes", atlas.probe_lit.size()},
                 {"surfels_seen", std::count(surfel_seen.begin(), surfel_seen.end(), 1)},
                 {"lightmap_caches", lightmap.size()},
                 {"lightmap_caches_valid", lightmap.validCount()},
                 {"lightmap_caches_pushed", std::count(lightmap.pushed.begin(), lightmap.pushed.end(), 1)},
                 {"lightmap_caches_sealed", std::count(lightmap.pushed.begin(), lightmap.pushed.end(), 2)},
                 {"direct_width", direct_texels.width},
                 {"direct_height", direct_texels.height},
                 {"direct_texels", direct_texels.size()},
                 {"direct_texels_valid", direct_texels.validCount()},
                 {"grid_caches", grid.size()},
                 {"grid_caches_valid", grid.validCount()},
                 {"grid_dims", {grid.dims.x, grid.dims.y, grid.dims.z}},
                 {"grid_spacing_m", grid.spacing_m}};
  nlohmann::ordered_json t = nlohmann::ordered_json::object();
  double total = 0.0;
  for (const auto& st : timings) {
    t[st.stage] = st.seconds;
    total += st.seconds;
  }
  t["total"] = total;
  j["seconds"] = t;
  const std::size_t surfel_bytes = bytesOf(surfels.position) + bytesOf(surfels.normal) + bytesOf(surfels.area) +
                                   bytesOf(surfels.albedo) + bytesOf(surfels.emission) +
                                   bytesOf(surfels.lightmap_uv) + bytesOf(surfels.mesh) + bytesOf(surfels.triangle) +
                                   bytesOf(surfels.barycentric);
  const std::size_t tree_bytes = bytesOf(tree.left) + bytesOf(tree.right) + bytesOf(tree.parent) +
                                 bytesOf(tree.begin) + bytesOf(tree.end) + bytesOf(tree.depth) + bytesOf(tree.area) +
                                 bytesOf(tree.bounds_min) + bytesOf(tree.bounds_max) + bytesOf(tree.centroid) +
                                 bytesOf(tree.mean_normal) + bytesOf(tree.level_begin) +
                                 bytesOf(tree.leaf_of_surfel) + bytesOf(tree.original_index);
  auto link_bytes = [](const links::Links& l) {
    return std::pair{l.linkCount() * l.bytesPerLinkProjected() + bytesOf(l.offsets),
                     l.linkCount() * links::Links::bytesPerLinkRuntime() + bytesOf(l.offsets)};
  };
  const auto [lm_sh, lm_rt] = link_bytes(lightmap_links);
  const auto [grid_sh, grid_rt] = link_bytes(grid_links);
  const int nc = options.bands * options.bands;
  j["memory_bytes"] = {
      {"surfels", surfel_bytes},
      {"tree", tree_bytes},
      {"lightmap_caches_sh_half", lightmap.size() * nc * 3 * 2},
      {"grid_caches_sh_half", grid.size() * nc * 3 * 2},
      {"lightmap_links_projected", lm_sh},
      {"lightmap_links_runtime", lm_rt},
      {"grid_links_projected", grid_sh},
      {"grid_links_runtime", grid_rt},
      {"sky_visibility", bytesOf(lightmap_links.sky) + bytesOf(grid_links.sky)}};
  j["links"] = {{"lightmap", linkStatsJson(lightmap_links)}, {"grid", linkStatsJson(grid_links)}};
  j["notes"] = notes;
  j["warnings"] = warnings;
  j["probe_lit"] = probe_lit_names;
  return j;
}

namespace {

// Every section of an artifact, in its order; `meta_text` holds the metadata's text until
// the writer has written it. save() and savePart() share it, so a part's sections are the
// artifact's in the same order and merge can assemble the artifact byte for byte.
Status addArtifactSections(const Precomputation& p, artifact::Writer& w, std::string& meta_text) {
  Status status;
  auto add = [&](const std::string& name, const auto& vec) {
    using T = typename std::decay_t<decltype(vec)>::value_type;
    if (status) status = w.addArray<T>(name, std::span<const T>(vec));
  };
  visitSmallArrays(p, add);
  visitLinkArrays("lmlink", p.lightmap_links, add);
  visitLinkArrays("gridlink", p.grid_links, add);
  nlohmann::ordered_json meta;
  meta["options"] = p.options.canonical();
  meta["bands"] = p.options.bands;
  meta["has_grid"] = p.has_grid;
  meta["lightmap"] = {{"width", p.lightmap.width}, {"height", p.lightmap.height},
                      {"texel_size_m", p.atlas.texel_size_m}, {"gutter_texels", p.atlas.gutter_texels},
                      {"generated_uv", p.atlas.generated}};
  meta["direct"] = {{"width", p.direct_texels.width}, {"height", p.direct_texels.height}};
  meta["grid"] = {{"origin", {p.grid.origin.x, p.grid.origin.y, p.grid.origin.z}},
                  {"spacing_m", p.grid.spacing_m},
                  {"dims", {p.grid.dims.x, p.grid.dims.y, p.grid.dims.z}}};
  meta["unreachable_fills"] = {{"lightmap", p.lightmap_fill.unreachable}, {"grid", p.grid_fill.unreachable}};
  // No timings in here: the same scene and options must give a bit-identical file.
  meta["notes"] = p.notes;
  meta["warnings"] = p.warnings;
  meta["probe_lit"] = p.probe_lit_names;
  meta_text = meta.dump();
  if (status) status = w.addString("meta", meta_text);
  return status;
}

}  // namespace

Status save(const Precomputation& p, const std::string& path, std::uint64_t cache_key) {
  artifact::Writer w(cache_key);
  std::string meta_text;
  if (Status s = addArtifactSections(p, w, meta_text); !s) return s;
  return w.write(path);
}

Status savePart(const Precomputation& p, const std::string& path, std::uint64_t cache_key,
                std::string_view scene_label) {
  if (!p.options.shard) return internalError("savePart: the precomputation was not run as a shard");
  artifact::Writer w(cache_key, artifact::FileKind::kShardPart);
  std::string meta_text;
  if (Status s = addArtifactSections(p, w, meta_text); !s) return s;
  // No times or host names: a rerun of the shard gives the same bytes.
  nlohmann::ordered_json part;
  part["format"] = kShardFormat;
  part["version"] = kShardFormatVersion;
  part["shard"] = p.options.shard->index;
  part["shards"] = p.options.shard->count;
  part["cache_key"] = artifact::cacheKeyHex(cache_key);
  part["scene"] = scene_label;
  part["options"] = p.options.canonical();
  part["lightmap_caches"] = {{"total", p.lightmap.size()},
                             {"begin", p.lightmap_linked.begin},
                             {"end", p.lightmap_linked.end}};
  part["grid_caches"] = {{"total", p.has_grid ? p.grid.size() : 0},
                         {"begin", p.grid_linked.begin},
                         {"end", p.grid_linked.end}};
  const std::string part_text = part.dump();
  if (Status s = w.addString(kShardSection, part_text); !s) return s;
  return w.write(path);
}

namespace {

// The metadata section, read without exceptions: every field is checked for presence, type
// and range before use, so a damaged 'meta' is a Status naming the field, never an uncaught
// nlohmann::json::type_error or an out-of-range float-to-int conversion.
class MetaReader {
 public:
  MetaReader(const nlohmann::json& meta, const std::string& path) : meta_(meta), path_(path) {}

  int integer(const char* group, const char* key, int index, long long lo, long long hi) {
    const nlohmann::json* v = field(group, key, index);
    if (v != nullptr && v->is_number_integer()) {
      // is_number_integer covers signed and unsigned storage; compare without converting
      // a huge unsigned value to a negative one.
      const bool fits = v->is_number_unsigned() ? v->get<std::uint64_t>() <= static_cast<std::uint64_t>(hi)
                                                : v->get<long long>() >= lo && v->get<long long>() <= hi;
      if (fits && v->get<long long>() >= lo) return static_cast<int>(v->get<long long>());
    }
    fail(group, key, index, v, fmt::format("an integer in [{}, {}]", lo, hi));
    return static_cast<int>(lo);
  }
  float number(const char* group, const char* key, int index) {
    const nlohmann::json* v = field(group, key, index);
    if (v != nullptr && v->is_number()) {
      const double d = v->get<double>();
      if (std::isfinite(d) && std::abs(d) <= double(std::numeric_limits<float>::max())) return static_cast<float>(d);
    }
    fail(group, key, index, v, "a finite number");
    return 0.0f;
  }
  bool boolean(const char* group, const char* key) {
    const nlohmann::json* v = field(group, key, -1);
    if (v != nullptr && v->is_boolean()) return v->get<bool>();
    fail(group, key, -1, v, "true or false");
    return false;
  }
  const Status& status() const { return status_; }

 private:
  const nlohmann::json* field(const char* group, const char* key, int index) const {
    const nlohmann::json* j = &meta_;
    if (group != nullptr) {
      const auto g = j->find(group);  // end() for a non-object
      if (g == j->end()) return nullptr;
      j = &*g;
    }
    const auto k = j->find(key);
    if (k == j->end()) return nullptr;
    j = &*k;
    if (index >= 0) {
      if (!j->is_array() || static_cast<std::size_t>(index) >= j->size()) return nullptr;
      j = &(*j)[static_cast<std::size_t>(index)];
    }
    return j;
  }
  void fail(const char* group, const char* key, int index, const nlohmann::json* v, std::string_view expected) {
    if (!status_) return;  // keep the first problem
    std::string name = group ? fmt::format("{}.{}", group, key) : std::string(key);
    if (index >= 0) name += fmt::format("[{}]", index);
    std::string got = v ? v->dump() : std::string("missing");
    if (got.size() > 40) got = got.substr(0, 37) + "...";
    status_ = invalidInput("artifact {}: meta field '{}' must be {} (is {})", path_, name, expected, got);
  }

  const nlohmann::json& meta_;
  const std::string& path_;
  Status status_;
};

// Largest |coordinate| in texels or grid cells accepted from an artifact (2^24, far below
// the 2^31 where a float-to-int conversion overflows).
constexpr double kMaxCellCoordinate = 16777216.0;

bool finite(float v) { return std::isfinite(v); }
bool finite(glm::vec2 v) { return std::isfinite(v.x) && std::isfinite(v.y); }
bool finite(glm::vec3 v) { return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z); }
bool finiteHalf(half_bits h) { return (h & 0x7c00u) != 0x7c00u; }  // exponent all ones: Inf or NaN

// Checks of an opened artifact, each naming the section and the element at fault. The relight
// (and the GPU backend) index arrays with stored indices in hot loops without checks, so every
// stored index is checked here once against the size of what it indexes, every array's size
// against the counts it must agree with, and every float for NaN/Inf. A corrupt artifact whose
// checksums were recomputed (or a buggy writer) is then rejected at open instead of read out of
// bounds later. Scene-dependent indices (surfel -> mesh) are checked by Relighter::create.
class StructureCheck {
 public:
  explicit StructureCheck(const std::string& path) : path_(path) {}
  const Status& status() const { return status_; }
  bool ok() const { return status_.isOk(); }

  template <typename... Args>
  void fail(fmt::format_string<Args...> f, Args&&... args) {
    if (status_) status_ = invalidInput("artifact {}: {}", path_, fmt::format(f, std::forward<Args>(args)...));
  }
  void size(std::string_view name, std::size_t actual, std::size_t expected) {
    if (ok() && actual != expected) fail("section '{}' has {} elements, expected {}", name, actual, expected);
  }
  template <typename T>
  void below(std::string_view name, std::span<const T> v, std::size_t bound) {
    for (std::size_t i = 0; ok() && i < v.size(); ++i)
      if (static_cast<std::size_t>(v[i]) >= bound) fail("section '{}' element {} = {} is not below {}", name, i, v[i], bound);
  }
  template <typename T>
  void allFinite(std::string_view name, std::span<const T> v) {
    for (std::size_t i = 0; ok() && i < v.size(); ++i)
      if (!finite(v[i])) fail("section '{}' element {} is not finite", name, i);
  }
  void allFiniteHalf(std::string_view name, std::span<const half_bits> v) {
    for (std::size_t i = 0; ok() && i < v.size(); ++i)
      if (!finiteHalf(v[i])) fail("section '{}' element {} is not a finite half float (bits {:#06x})", name, i, v[i]);
  }
  // CSR offsets: count + 1 entries from 0, non-decreasing, ending at `total`.
  void offsets(std::string_view name, std::span<const std::uint32_t> v, std::size_t count, std::size_t total) {
    size(name, v.size(), count + 1);
    if (!ok()) return;
    if (v.front() != 0) return fail("section '{}' starts at {}, expected 0", name, v.front());
    for (std::size_t i = 0; ok() && i + 1 < v.size(); ++i)
      if (v[i + 1] < v[i]) fail("section '{}' decreases at element {} ({} after {})", name, i + 1, v[i + 1], v[i]);
    if (ok() && v.back() != total) fail("section '{}' ends at {}, expected {}", name, v.back(), total);
  }
  // A fill plan over `n` caches (or texels): targets and sources below n, CSR offsets.
  void fillPlan(const char* prefix, const caches::FillPlan& plan, std::size_t n) {
    if (plan.source_begin.empty() && plan.target.empty() && plan.source.empty()) return;  // no plan
    below<std::uint32_t>(fmt::format("{}.target", prefix), plan.target, n);
    offsets(fmt::format("{}.begin", prefix), plan.source_begin, plan.target.size(), plan.source.size());
    below<std::uint32_t>(fmt::format("{}.source", prefix), plan.source, n);
  }
  void links(const char* prefix, const links::LinksView& l, std::size_t caches, std::size_t nodes) {
    const std::size_t nc = static_cast<std::size_t>(l.bands) * static_cast<std::size_t>(l.bands);
    if (caches == 0 && l.offsets.empty()) {  // no caches of this kind: no links either
      for (std::size_t n : {l.node.size(), l.coeffs.size(), l.direction.size(), l.solid_angle.size(), l.sky.size()})
        if (ok() && n != 0) fail("'{}.*' sections hold links for caches the artifact does not have", prefix);
      return;
    }
    const std::size_t count = l.node.size();
    offsets(fmt::format("{}.offsets", prefix), l.offsets, caches, count);
    below<std::uint32_t>(fmt::format("{}.node", prefix), l.node, nodes);
    size(fmt::format("{}.coeffs", prefix), l.coeffs.size(), count * nc);
    size(fmt::format("{}.direction", prefix), l.direction.size(), count);
    size(fmt::format("{}.solid_angle", prefix), l.solid_angle.size(), count);
    size(fmt::format("{}.sky", prefix), l.sky.size(), caches * nc);
    allFiniteHalf(fmt::format("{}.coeffs", prefix), l.coeffs);
    allFiniteHalf(fmt::format("{}.solid_angle", prefix), l.solid_angle);
    allFinite<float>(fmt::format("{}.sky", prefix), l.sky);
  }

 private:
  const std::string& path_;
  Status status_;
};

Status checkSurfelsAndTree(const Precomputation& p, StructureCheck& c) {
  const surfels::Surfels& s = p.surfels;
  const std::size_t ns = s.size();
  if (ns == 0) c.fail("has no surfels");
  c.size("surfel.normal", s.normal.size(), ns);
  c.size("surfel.area", s.area.size(), ns);
  c.size("surfel.albedo", s.albedo.size(), ns);
  c.size("surfel.emission", s.emission.size(), ns);
  c.size("surfel.lightmap_uv", s.lightmap_uv.size(), ns);
  c.size("surfel.mesh", s.mesh.size(), ns);
  c.size("surfel.triangle", s.triangle.size(), ns);
  c.size("surfel.barycentric", s.barycentric.size(), ns);
  c.allFinite<glm::vec3>("surfel.position", s.position);
  c.allFinite<glm::vec3>("surfel.normal", s.normal);
  c.allFinite<float>("surfel.area", s.area);
  c.allFinite<glm::vec3>("surfel.albedo", s.albedo);
  c.allFinite<glm::vec3>("surfel.emission", s.emission);
  c.allFinite<glm::vec2>("surfel.lightmap_uv", s.lightmap_uv);
  c.allFinite<glm::vec2>("surfel.barycentric", s.barycentric);
  c.size("surfel.seen", p.surfel_seen.size(), ns);
  c.below<std::uint8_t>("surfel.seen", p.surfel_seen, 2);
  if (!c.ok()) return c.status();

  const hierarchy::Tree& t = p.tree;
  const std::size_t nodes = 2 * ns - 1;
  c.size("tree.left", t.left.size(), nodes);
  c.size("tree.right", t.right.size(), nodes);
  c.size("tree.parent", t.parent.size(), nodes);
  c.size("tree.begin", t.begin.size(), nodes);
  c.size("tree.end", t.end.size(), nodes);
  c.size("tree.depth", t.depth.size(), nodes);
  c.size("tree.area", t.area.size(), nodes);
  c.size("tree.bounds_min", t.bounds_min.size(), nodes);
  c.size("tree.bounds_max", t.bounds_max.size(), nodes);
  c.size("tree.centroid", t.centroid.size(), nodes);
  c.size("tree.mean_normal", t.mean_normal.size(), nodes);
  c.size("tree.leaf_of_surfel", t.leaf_of_surfel.size(), ns);
  c.size("tree.original_index", t.original_index.size(), ns);
  c.allFinite<float>("tree.area", t.area);
  c.allFinite<glm::vec3>("tree.bounds_min", t.bounds_min);
  c.allFinite<glm::vec3>("tree.bounds_max", t.bounds_max);
  c.allFinite<glm::vec3>("tree.centroid", t.centroid);
  c.allFinite<glm::vec3>("tree.mean_normal", t.mean_normal);
  c.below<std::uint32_t>("tree.original_index", t.original_index, ns);
  if (!c.ok()) return c.status();
  if (t.level_begin.size() < 2) {
    c.fail("section 'tree.level_begin' has {} elements, needs at least 2", t.level_begin.size());
    return c.status();
  }

  // A binary tree in breadth-first order: children after their parent and pointing back to
  // it, each node covering the contiguous surfel range of its children, leaves one surfel.
  // With 2n - 1 nodes and n leaves this makes every non-root node the child of exactly one
  // node, so bottom-up loops (reverse node order) and top-down ones visit each once.
  if (t.parent[0] != -1) c.fail("section 'tree.parent' gives the root parent {}, expected -1", t.parent[0]);
  if (t.depth[0] != 0) c.fail("section 'tree.depth' gives the root depth {}, expected 0", t.depth[0]);
  std::size_t leaves = 0;
  for (std::size_t n = 0; c.ok() && n < nodes; ++n) {
    const std::int64_t l = t.left[n], r = t.right[n];
    if (n > 0 && !(t.parent[n] >= 0 && static_cast<std::size_t>(t.parent[n]) < n))
      c.fail("section 'tree.parent' element {} = {} is not an earlier node", n, t.parent[n]);
    else if (t.begin[n] > t.end[n] || t.end[n] > ns)
      c.fail("tree node {} covers surfels [{}, {}) of {}", n, t.begin[n], t.end[n], ns);
    else if (t.depth[n] + std::size_t(1) >= t.level_begin.size() || n < t.level_begin[t.depth[n]] ||
             n >= t.level_begin[t.depth[n] + 1])
      c.fail("tree node {} (depth {}) lies outside its level in 'tree.level_begin'", n, t.depth[n]);
    else if (l < 0 || r < 0) {
      if (l != -1 || r != -1) c.fail("tree node {} has children {} and {}: both or neither must be -1", n, l, r);
      else if (t.end[n] != t.begin[n] + 1) c.fail("tree leaf {} covers {} surfels, expected 1", n, t.end[n] - t.begin[n]);
      ++leaves;
    } else if (l <= std::int64_t(n) || r <= std::int64_t(n) || l == r || std::size_t(l) >= nodes ||
               std::size_t(r) >= nodes) {
      c.fail("tree node {} has children {} and {} (must be distinct later nodes below {})", n, l, r, nodes);
    } else if (t.parent[l] != std::int64_t(n) || t.parent[r] != std::int64_t(n) ||
               t.depth[l] != t.depth[n] + 1 || t.depth[r] != t.depth[n] + 1) {
      c.fail("tree node {}: its children {} and {} do not name it as parent one level down", n, l, r);
    } else if (t.begin[l] != t.begin[n] || t.end[l] != t.begin[r] || t.end[r] != t.end[n]) {
      c.fail("tree node {}: its children's surfel ranges do not split its own", n);
    }
  }
  if (!c.ok()) return c.status();
  if (leaves != ns) c.fail("the tree has {} leaves for {} surfels", leaves, ns);
  const auto& lb = t.level_begin;
  if (lb.front() != 0 || lb.back() != nodes || !std::is_sorted(lb.begin(), lb.end()))
    c.fail("section 'tree.level_begin' does not split [0, {}) into levels", nodes);
  for (std::size_t s = 0; c.ok() && s < ns; ++s) {
    const std::uint32_t leaf = t.leaf_of_surfel[s];
    if (leaf >= nodes || t.left[leaf] >= 0 || t.begin[leaf] != s)
      c.fail("section 'tree.leaf_of_surfel' element {} = {} is not the leaf of surfel {}", s, leaf, s);
  }
  return c.status();
}

// A set of lightmap-texel points (the caches, or the direct layer's texels) under section
// prefix `sec`: sizes, finite values, and texel <-> point indices that agree.
void checkTexelPoints(const caches::LightmapCaches& lm, const char* sec, StructureCheck& c) {
  const std::size_t texels = static_cast<std::size_t>(lm.width) * static_cast<std::size_t>(lm.height);
  const std::size_t nc = lm.size();
  auto name = [&](const char* field) { return fmt::format("{}.{}", sec, field); };
  c.size(name("cache_of_texel"), lm.cache_of_texel.size(), texels);
  c.size(name("normal"), lm.normal.size(), nc);
  c.size(name("texel"), lm.texel.size(), nc);
  c.size(name("mesh"), lm.mesh.size(), nc);
  c.size(name("triangle"), lm.triangle.size(), nc);
  c.size(name("valid"), lm.valid.size(), nc);
  c.size(name("pushed"), lm.pushed.size(), nc);
  c.allFinite<glm::vec3>(name("position"), lm.position);
  c.allFinite<glm::vec3>(name("normal"), lm.normal);
  c.below<std::uint32_t>(name("texel"), lm.texel, texels);
  for (std::size_t t = 0; c.ok() && t < texels; ++t) {
    const std::int32_t cache = lm.cache_of_texel[t];
    if (cache < -1 || (cache >= 0 && static_cast<std::size_t>(cache) >= nc))
      c.fail("section '{}.cache_of_texel' element {} = {} is not -1 or a cache below {}", sec, t, cache, nc);
  }
  for (std::size_t i = 0; c.ok() && i < nc; ++i)
    if (lm.cache_of_texel[lm.texel[i]] != std::int32_t(i))
      c.fail("sections '{0}.texel' and '{0}.cache_of_texel' disagree about point {1}", sec, i);
}

Status checkCachesAndLinks(const LoadedPrecomputation& l, StructureCheck& c) {
  const Precomputation& p = l.p;
  const caches::LightmapCaches& lm = p.lightmap;
  const std::size_t texels = static_cast<std::size_t>(lm.width) * static_cast<std::size_t>(lm.height);
  const std::size_t nc = lm.size();
  checkTexelPoints(lm, "lm", c);
  const caches::LightmapCaches& dt = p.direct_texels;
  if (c.ok() && (dt.width == 0) != (dt.height == 0))
    c.fail("direct layer {}x{}: width and height must both be 0 or both positive", dt.width, dt.height);
  if (c.ok() && dt.width > 0 &&
      (dt.width % lm.width != 0 || dt.height % lm.height != 0 || dt.width / lm.width != dt.height / lm.height ||
       dt.width / lm.width < 2 || dt.width / lm.width > kMaxDirectScale))
    c.fail("direct layer {}x{} is not the {}x{} lightmap scaled by 2..{}", dt.width, dt.height, lm.width, lm.height,
           kMaxDirectScale);
  checkTexelPoints(dt, "dt", c);

  const caches::GridCaches& g = p.grid;
  const std::size_t ng = g.size();
  c.size("grid.valid", g.valid.size(), ng);
  c.allFinite<glm::vec3>("grid.position", g.position);
  if (c.ok() && !p.has_grid && ng != 0) c.fail("has {} grid caches but its metadata says it has no grid", ng);
  if (c.ok() && static_cast<std::size_t>(g.dims.x) * std::size_t(g.dims.y) * std::size_t(g.dims.z) != ng)
    c.fail("grid dims {}x{}x{} do not match its {} grid caches", g.dims.x, g.dims.y, g.dims.z, ng);

  if (c.ok() && p.has_grid && !(g.spacing_m > 0.0f))
    c.fail("grid spacing {} m is not positive", g.spacing_m);

  // The relight turns surfel coordinates into integer texel and grid-cell indices (bilinear
  // lightmap gather, trilinear grid gather). No real surfel lies millions of texels or cells
  // away from the atlas or the grid; one that does would overflow the int conversion.
  const double res = std::max(lm.width, lm.height);
  for (std::size_t i = 0; c.ok() && i < p.surfels.size(); ++i) {
    const glm::vec2 uv = p.surfels.lightmap_uv[i];
    if (std::abs(uv.x) * res > kMaxCellCoordinate || std::abs(uv.y) * res > kMaxCellCoordinate)
      c.fail("section 'surfel.lightmap_uv' element {} = ({}, {}) lies millions of texels outside the atlas", i,
             uv.x, uv.y);
    if (p.has_grid) {
      const glm::dvec3 cell = (glm::dvec3(p.surfels.position[i]) - glm::dvec3(g.origin)) / double(g.spacing_m);
      if (glm::any(glm::greaterThan(glm::abs(cell), glm::dvec3(kMaxCellCoordinate))))
        c.fail("section 'surfel.position' element {} lies millions of grid cells outside the grid", i);
    }
  }

  c.fillPlan("lmfill", p.lightmap_fill, nc);
  c.fillPlan("gridfill", p.grid_fill, ng);
  c.fillPlan("dilate", p.dilation, texels);
  c.fillPlan("dtfill", p.direct_fill, dt.size());
  c.fillPlan("dtdilate", p.direct_dilation, std::size_t(dt.width) * std::size_t(dt.height));
  const std::size_t nodes = p.tree.nodeCount();
  c.links("lmlink", l.lightmap_links, nc, nodes);
  c.links("gridlink", l.grid_links, ng, nodes);
  return c.status();
}

}  // namespace

Expected<LoadedPrecomputation> open(const std::string& path) {
  auto file = artifact::Artifact::open(path);
  if (!file) return file.status();
  LoadedPrecomputation out{std::move(file).value(), {}, {}, {}, {}};
  auto meta_text = out.file.string("meta");
  if (!meta_text) return meta_text.status();
  out.meta = nlohmann::json::parse(*meta_text, nullptr, /*allow_exceptions=*/false);
  if (out.meta.is_discarded() || !out.meta.is_object())
    return invalidInput("artifact {}: the 'meta' section is not valid lightlink metadata (not a JSON object)", path);
  Status status;
  auto copy = [&](const std::string& name, auto& vec) {
    using T = typename std::decay_t<decltype(vec)>::value_type;
    if (!status) return;
    auto s = out.file.array<T>(name);
    if (!s) {
      status = s.status();
      return;
    }
    vec.assign(s->begin(), s->end());
  };
  visitSmallArrays(out.p, copy);
  if (!status) return status;

  MetaReader meta(out.meta, path);
  const int bands = meta.integer(nullptr, "bands", -1, 1, 4);
  out.p.has_grid = meta.boolean(nullptr, "has_grid");
  out.p.lightmap.width = meta.integer("lightmap", "width", -1, 1, charts::kMaxAtlasResolution);
  out.p.lightmap.height = meta.integer("lightmap", "height", -1, 1, charts::kMaxAtlasResolution);
  out.p.atlas.resolution = out.p.lightmap.width;
  // Pages are stacked along v (charts::LightmapAtlas).
  out.p.atlas.pages = std::max(1, out.p.lightmap.height / std::max(1, out.p.lightmap.width));
  out.p.atlas.texel_size_m = meta.number("lightmap", "texel_size_m", -1);
  out.p.atlas.gutter_texels = meta.integer("lightmap", "gutter_texels", -1, 0, charts::kMaxAtlasResolution);
  out.p.atlas.generated = meta.boolean("lightmap", "generated_uv");
  out.p.options.bands = bands;
  out.p.direct_texels.width = meta.integer("direct", "width", -1, 0, charts::kMaxAtlasResolution);
  out.p.direct_texels.height = meta.integer("direct", "height", -1, 0, charts::kMaxAtlasResolution);
  for (int i = 0; i < 3; ++i) {
    out.p.grid.origin[i] = meta.number("grid", "origin", i);
    out.p.grid.dims[i] = meta.integer("grid", "dims", i, 0, 1 << 16);
  }
  out.p.grid.spacing_m = meta.number("grid", "spacing_m", -1);
  if (!meta.status()) return meta.status();

  auto view = [&](const char* prefix, links::LinksView& spans) {
    spans.bands = bands;
    auto bind = [&](const std::string& name, auto& span) {
      using T = typename std::decay_t<decltype(span)>::element_type;
      if (!status) return;
      auto s = out.file.array<std::remove_const_t<T>>(name);
      if (!s) status = s.status();
      else span = *s;
    };
    visitLinkArrays(prefix, spans, bind);
  };
  view("lmlink", out.lightmap_links);
  view("gridlink", out.grid_links);
  if (!status) return status;

  StructureCheck check(path);
  if (Status s = checkSurfelsAndTree(out.p, check); !s) return s;
  if (Status s = checkCachesAndLinks(out, check); !s) return s;
  return out;
}

namespace {

// The glTF JSON of a .gltf file or of a .glb's first chunk; empty when it cannot be found
// (the loader reports malformed files; the key then covers the bytes alone).
std::string_view gltfJson(const std::string& data) {
  if (data.size() >= 20 && data.compare(0, 4, "glTF") == 0) {
    std::uint32_t length = 0, type = 0;
    std::memcpy(&length, data.data() + 12, 4);
    std::memcpy(&type, data.data() + 16, 4);
    if (type != 0x4E4F534Au || length > data.size() - 20) return {};
    return std::string_view(data).substr(20, length);
  }
  return data;
}

}  // namespace

Expected<std::uint64_t> cacheKeyFor(const std::string& scene_path, const PrecomputeOptions& options,
                                    const scene::FileAccess& access) {
  auto files = scene::SceneFiles::forScene(scene_path, access);
  if (!files) return files.status();
  auto data = files->readScene();
  if (!data) return data.status();
  // The key covers exactly what the result depends on: the scene file, its external buffers
  // (geometry) and the images the loader decodes for lighting (albedo, emission;
  // core/scene/lighting_images.h). A normal or metallic map is never read, so editing one
  // keeps the artifact. Each external file is appended as (uri, size, bytes), in the JSON's order.
  std::string keyed = std::move(data).value();
  if (scene::isAssimpScenePath(scene_path)) {  // OBJ: its .mtl files and textures (obj_files.h)
    auto deps = scene::objDependencyBytes(*files, keyed);
    if (!deps) return deps.status();
    keyed += *deps;
    return artifact::cacheKey(std::as_bytes(std::span<const char>(keyed.data(), keyed.size())), options.canonical());
  }
  const nlohmann::json j = nlohmann::json::parse(gltfJson(keyed), nullptr, /*allow_exceptions=*/false);
  if (!j.is_discarded() && j.is_object()) {
    const scene::LightingImages lighting = scene::lightingImages(j);
    std::string external;
    for (const char* list : {"buffers", "images"}) {
      const bool images = std::string_view(list) == "images";
      const auto it = j.find(list);
      if (it == j.end() || !it->is_array()) continue;
      for (std::size_t i = 0; i < it->size(); ++i) {
        const nlohmann::json& entry = (*it)[i];
        if (!entry.is_object() || !entry.contains("uri") || !entry["uri"].is_string()) continue;
        const std::string uri = entry["uri"].get<std::string>();
        if (uri.rfind("data:", 0) == 0) continue;  // embedded: already in the bytes
        const std::string what = fmt::format("{}[{}].uri", list, i);
        if (images && !lighting.image(static_cast<int>(i))) {
          // Not read, but refused as the loader refuses it when it leaves the folder.
          if (auto where = files->resolveUri(uri, what); !where) return where.status();
          continue;
        }
        auto bytes = files->readUri(uri, what);
        // A missing or unreadable image is a warning to the loader (the material falls back
        // to its factor), so it is keyed as such; restoring the file then changes the key.
        if (!bytes && images && (bytes.status().code() == Code::kNotFound || bytes.status().code() == Code::kIoError)) {
          external += fmt::format("{}\nunreadable\n", uri);
          continue;
        }
        if (!bytes) return bytes.status();
        external += fmt::format("{}\n{}\n", uri, bytes->size());
        external += *bytes;
      }
    }
    keyed += external;
  }
  return artifact::cacheKey(std::as_bytes(std::span<const char>(keyed.data(), keyed.size())), options.canonical());
}

}  // namespace lightlink::precompute
