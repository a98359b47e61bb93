// Precompute: the once-per-scene pipeline of seed 000 sec 3-4, end to end.
//
//   scene --unwrap (when a static mesh lacks TEXCOORD_1)--> lightmap atlas
//         --surfels--> --hierarchy--> --caches (lightmap texels, grid)--> --links-->
//   Precomputation (in memory) --save--> artifact (.llk) --open--> LoadedPrecomputation
//
// Each stage is its own module; this one only orders them, times them, reports progress and
// memory (seed 000 Table 4) and decides which optional parts the scene calls for (a grid
// only when the scene has dynamic meshes or a grid is asked for). The artifact's cache key
// covers the scene file's bytes, the canonical option string and the format version, so a
// matching artifact can be reused instead of recomputed.
#pragma once

#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include <nlohmann/json.hpp>

#include "core/artifact/artifact.h"
#include "core/caches/caches.h"
#include "core/charts/unwrap.h"
#include "core/common/progress.h"
#include "core/common/status.h"
#include "core/hierarchy/tree.h"
#include "core/links/links.h"
#include "core/scene/scene.h"
#include "core/scene/scene_files.h"
#include "core/scene/surface_rules.h"
#include "core/surfels/surfels.h"

namespace lightlink::precompute {

enum class GridMode { kAuto, kOn, kOff };

// Budgets of one precompute, checked before the work they bound so that a request over one
// fails at once with Code::kResourceExhausted naming the limit and the value (docs/cli.md
// "Limits", docs/service.md "Limits"). Not part of the cache key: a limit decides whether a
// result is computed, never what it is.
struct PrecomputeLimits {
  // Lightmap texels (width x height): every later stage keeps per-texel arrays.
  std::uint64_t max_texels = std::uint64_t(4096) * 4096;
  // Link arrays of all caches, estimated as caches x links per cache x bytes per link
  // before link generation. 0 = half of this machine's physical memory.
  std::uint64_t max_link_bytes = 0;
};

// The link bytes `caches` caches may take at `max_links` links each and `bands` SH bands
// (projected and runtime forms), the figure max_link_bytes is checked against.
std::uint64_t linkBytesEstimate(std::uint64_t caches, int max_links, int bands);

// max_link_bytes with 0 resolved to half of the physical memory.
std::uint64_t effectiveLinkBudget(const PrecomputeLimits& limits);

// The finest direct layer: direct_scale texels per lightmap texel along each axis.
inline constexpr int kMaxDirectScale = 8;

// One share of a sharded precompute (docs/farm.md): shard `index` of `count` links the
// caches of its contiguous range of all caches (lightmap caches, then grid caches); every
// other stage runs whole on every shard, since each is deterministic and needed to link.
struct ShardSpec {
  int index = 0;
  int count = 1;
};

// "I/N" with 0 <= I < N <= kMaxShards; the message names the text otherwise.
inline constexpr int kMaxShards = 4096;
Expected<ShardSpec> parseShard(std::string_view text);

// Caches [begin, end) of `total` that shard `s` links: a contiguous, deterministic split.
struct CacheRange {
  std::size_t begin = 0, end = 0;
};
CacheRange shardRange(std::size_t total, const ShardSpec& s);

struct PrecomputeOptions {
  std::uint32_t surfels = 32768;   // nS
  int links = 128;                 // nL, most links per cache
  int bands = 3;                   // SH bands of the projected links, 1..4
  int rays = 1024;                 // link rays per cache
  hierarchy::Builder builder = hierarchy::Builder::kAgglomerative;
  GridMode grid = GridMode::kAuto; // auto: a grid only when the scene has dynamic meshes
  float grid_spacing_m = 0.0f;     // 0 = derived from grid_resolution
  int grid_resolution = 16;        // grid points along the longest axis when spacing is 0
  // Lightmap density (charts::UnwrapOptions; docs/lightmaps.md): a texel size in scene units,
  // or, unset, the size at which the charts cover about `texel_budget` texels; the atlas is
  // packed onto pages of at most `max_atlas` (or exactly `lightmap_resolution`) texels.
  std::optional<float> texel_size_m;
  std::uint64_t texel_budget = 0;  // the presets set one
  int max_atlas = 1024;
  int max_pages = 0;               // 0 = as many as needed; else the texel size is raised to fit
  std::optional<int> lightmap_resolution;
  int target_resolution = 128;     // with texel_budget 0 and no texel size: one atlas this size
  charts::UvMode uv_mode = charts::UvMode::kAuto;  // what happens to an existing TEXCOORD_1
  // Direct texels per lightmap texel along each axis, 1..8 (Unity's lightmap vs indirect
  // resolution): above 1 the baked direct light gets its own atlas of the same charts, this
  // many times finer, so baked shadows are crisp while the indirect caches stay cheap to relight.
  int direct_scale = 1;
  int validity_rays = 64;
  std::uint64_t seed = 1;
  // Lighting flags set by a bake config over the scene file's (--surfaces): applied to the
  // loaded scene by whoever loads it for a precompute (scene::applySurfaceRules).
  scene::SurfaceRules surfaces;
  PrecomputeLimits limits;         // not in canonical(): budgets, not parameters of the result
  // Set: link only this shard's caches (a part for `lightlink merge`, savePart()). Not in
  // canonical(): every shard and the merged artifact carry the whole run's key.
  std::optional<ShardSpec> shard;

  Status validate() const;
  // Every option that changes the result, in a fixed order, and kGeneratorRevision: part of
  // the cache key.
  std::string canonical() const;
  // The link generation these options ask for (rays, budget, bands, seed): what run() links
  // with, and what a benchmark must use to link the same way.
  links::LinkOptions linkOptions() const {
    return {.rays = rays, .max_links = links, .bands = bands, .seed = seed};
  }
};

// Bumped whenever the same scene and options give different artifact contents (not a format
// change: readers accept both). Part of the cache key, so a daemon's cache directory never
// reuses an artifact an older generator made. 2: owner rasters and 32-bit ray jitter in
// link generation. 3: link rays from one base pattern randomised per cache (LinkRays).
// 4: alpha cut-outs and cast_shadows honoured by every ray, texels over cut-outs invalid,
// no surfels in cut-outs; caches placed within their texel's footprint. 5: each side of a
// double-sided surface has its own surfels; caches on double-sided contacts move off them.
// 6: caches sealed in a pocket (every validity ray stops within a texel) move to an open
// valid point of their footprint.
inline constexpr int kGeneratorRevision = 6;

// Named quality presets for `lightlink bake` and the daemon: "draft", "medium" (seed 000
// Table 2 setting 2: nS 32k, nL 128, 3 bands) and "high", chosen on the accuracy study's
// Pareto front (bench/accuracy; rule, measured error and cost in docs/quality.md).
Expected<PrecomputeOptions> preset(std::string_view name);

struct StageTime {
  std::string stage;
  double seconds = 0.0;
};

struct Precomputation {
  PrecomputeOptions options;
  charts::LightmapAtlas atlas;
  surfels::Surfels surfels;  // in tree order
  hierarchy::Tree tree;
  caches::LightmapCaches lightmap;
  bool has_grid = false;
  caches::GridCaches grid;
  links::Links lightmap_links;
  links::Links grid_links;
  // Per surfel (tree order): 1 when a ray of some cache (lightmap or grid) was credited to
  // it. Node radiosity is averaged over these alone (relight::pullAreas).
  std::vector<std::uint8_t> surfel_seen;
  caches::FillPlan lightmap_fill, grid_fill, dilation;
  // The direct layer's own texels when options.direct_scale > 1 (same charts, the atlas
  // direct_scale times finer; positions, normals and validity as for caches, no links), with
  // its fill and dilation plans. Empty (width 0): the direct light lives at the caches.
  caches::LightmapCaches direct_texels;
  caches::FillPlan direct_fill, direct_dilation;
  bool hasDirectLayer() const { return direct_texels.width > 0; }
  std::vector<StageTime> timings;
  std::vector<std::string> notes;  // decisions taken (what was skipped and why)
  std::vector<std::string> warnings;  // findings a user should act on (the unwrap's: uv1 replaced, charts scaled down)
  std::vector<std::string> probe_lit_names;  // static meshes lit from the grid, not the lightmap
  // With options.shard: the caches this shard linked (lightmap_links and grid_links hold
  // those alone, surfel_seen the surfels they saw).
  CacheRange lightmap_linked, grid_linked;

  // Report: counts, time per stage, memory per structure, rays and rays/s.
  nlohmann::ordered_json report() const;
};

// The unwrap stage alone, with the options precompute uses: a caller that reuses an artifact
// runs it to give the scene the same lightmap UVs (and triangle ids) the artifact was made on.
// `progress` is polled for cancellation.
Expected<charts::UnwrapResult> unwrapFor(scene::Scene& scene, const PrecomputeOptions& options,
                                         const Progress* progress = nullptr);

// Runs every stage. `scene` is modified: the unwrap writes uv1 (and splits seam vertices).
// Every stage polls progress->cancelled() and stops with Code::kCancelled; a request over
// options.limits, or std::bad_alloc in any stage, gives Code::kResourceExhausted.
Expected<Precomputation> run(scene::Scene& scene, const PrecomputeOptions& options,
                             Progress* progress = nullptr);

// Writes the precomputation atomically as one artifact keyed by `cache_key`.
Status save(const Precomputation& p, const std::string& path, std::uint64_t cache_key);

// The part's own section and its JSON's format name and version (bumped when its fields change).
inline constexpr const char* kShardSection = "shard";
inline constexpr const char* kShardFormat = "lightlink.shard";
inline constexpr int kShardFormatVersion = 1;

// Writes a shard's precomputation (run with options.shard) as a part (artifact::FileKind::
// kShardPart): the artifact's sections in the same order, the link sections holding only its
// caches, then a "shard" section (JSON: shard, shards, cache ranges, key) that merge checks.
// `scene_label` is recorded for messages only.
Status savePart(const Precomputation& p, const std::string& path, std::uint64_t cache_key,
                std::string_view scene_label);

// The artifact mapped back. The link arrays (the bulk of the file) stay in the mapping and
// are read through spans; the small structures (surfels, tree, caches, plans) are copied
// into a Precomputation whose `lightmap_links`/`grid_links` vectors stay empty.
// open() trusts nothing it reads, checksums or not: every metadata field is type- and
// range-checked, every stored index (tree children and parents, cache texels, fill plans,
// link offsets and nodes) is checked against what it indexes, every array size against the
// counts it must match, every float for NaN/Inf. What it returns is safe to relight; what it
// rejects gets a Status naming the file, the section and the element (tests/fuzz).
struct LoadedPrecomputation {
  artifact::Artifact file;
  Precomputation p;
  nlohmann::json meta;
  links::LinksView lightmap_links, grid_links;
};

Expected<LoadedPrecomputation> open(const std::string& path);

// Key for reusing an artifact: the scene file's bytes + options + format version. The files
// the scene names are read under `access`, as the loader reads them (scene_files.h).
Expected<std::uint64_t> cacheKeyFor(const std::string& scene_path, const PrecomputeOptions& options,
                                    const scene::FileAccess& access = {});

}  // namespace lightlink::precompute
