// Lightmap UVs for a whole scene: one atlas shared by every static MeshInstance.
//
// unwrap() fills MeshInstance::uv1 (glTF TEXCOORD_1) for static meshes so that every
// texel of the atlas belongs to at most one surface point: charts do not overlap, keep
// `gutter_texels` empty texels between them (bilinear filtering plus dilation), no
// triangle is flipped and area stretch is bounded. Pipeline, one file per stage:
// mesh_prep (weld, OpenMesh, non-manifold split) -> segment (region growing) -> flatten
// (planar projection or LSCM, split until valid) -> pack (minimal boxes, skyline) ->
// rasterize (the atlas check that fills the report). Deterministic: the same scene and
// options give identical bytes at any thread count.
//
// Existing TEXCOORD_1 (`uv_mode`): when every static mesh has one, kAuto and kKeep keep
// them bit-exactly, at the resolution the layout was packed for (the smallest power of two
// at which its uv islands stay `gutter_texels` apart, unless `resolution` is given), and
// check them (overlaps, flips, out of [0,1]); kAuto regenerates instead, with a warning,
// when that check finds overlapping or out-of-range uv1, kKeep keeps it with warnings. If
// some static meshes lack it, or with kGenerate, uv1 is regenerated for all static meshes
// (one consistent atlas; a warning names the meshes whose uv1 was replaced). Dynamic meshes
// are never touched.
//
// Generating splits vertices along chart seams: positions, normals, uv0 and indices of a
// generated mesh are rewritten (degenerate faces dropped) and `MeshLightmap::source_vertex`
// maps each new vertex to the vertex it was copied from, so writers can re-emit any other
// attribute.
#pragma once

#include <cstdint>
#include <optional>
#include <vector>

#include "core/charts/rasterize.h"  // kNoChart
#include "core/charts/report.h"
#include "core/common/progress.h"
#include "core/common/status.h"
#include "core/scene/scene.h"

namespace lightlink::charts {

inline constexpr int kMaxAtlasResolution = 16384;

// What happens to an existing TEXCOORD_1 (`--uv keep|generate|auto`).
enum class UvMode { kAuto, kKeep, kGenerate };

// Density model (docs/lightmaps.md): the atlas is laid out at a texel size in scene units
// (metres), given or derived, and packed onto as many square pages as it needs. Pages are
// stacked along v in one atlas `resolution` wide and `pages * resolution` tall, page p at
// rows [p * resolution, (p + 1) * resolution); no chart straddles two pages, so each page
// is a self-contained lightmap. Per mesh, MeshInstance::lightmap_scale multiplies the
// density; a chart larger than a page is scaled down to fit (with a warning).
struct UnwrapOptions {
  // Metres of surface per texel. Unset: derived from `texel_budget` when that is set, else
  // the smallest size at which all charts fit into one `resolution` (or `target_resolution`)
  // atlas.
  std::optional<float> texel_size_m;
  // The texel size rule: the size at which the charts cover about this many texels (every
  // chart's area in texels plus the texels its border adds: docs/lightmaps.md). 0 = unused.
  std::uint64_t texel_budget = 0;
  // Page width = height in texels. Unset: the smallest power of two up to `max_atlas` that
  // holds every chart on one page, else pages of `max_atlas` (or `target_resolution` when
  // neither the texel size nor the budget is set).
  std::optional<int> resolution;
  int max_atlas = 1024;
  // Most pages; 0 = as many as needed. More needed: the texel size is raised until they fit
  // (with a warning).
  int max_pages = 0;
  int target_resolution = 1024;
  // Objects too small for the lightmap (every chart of the mesh under 2x2 texels at the
  // chosen size) become probe-lit (MeshInstance::probe_lit) instead of taking atlas space.
  // Applies when the texel size is given or derived from the budget.
  bool probe_lit_small = true;
  int gutter_texels = 2;            // empty texels between charts and at the atlas border
  float normal_cone_deg = 60.0f;    // charting: max face normal deviation from the chart normal
  float hard_edge_deg = 60.0f;      // charting: dihedral angle that always cuts charts
  float planar_deg = 5.0f;          // flattening: charts flatter than this are projected
  float max_stretch = 2.0f;         // flattening: per-triangle area stretch limit (> 1)
  float min_chart_fill = 0.5f;      // flattening: charts (8+ faces) covering less of their
                                    // minimal box are split (curved strips pack badly)
  float weld_tolerance = 1e-6f;     // weld distance as a fraction of Scene::scale
  UvMode uv_mode = UvMode::kAuto;
  // Most texels the atlas may have (width x height), checked before any packing; 0 = no
  // limit. Over it: Code::kResourceExhausted naming the limit.
  std::uint64_t max_texels = 0;
  // Polled for cancellation only (Progress::cancelled); a cancelled unwrap returns kCancelled.
  const Progress* progress = nullptr;
};

// Checks ranges; the message names the option and the accepted range.
Status validate(const UnwrapOptions& options);

// The texel size rule: x = 1 / texel solves  sum_c (A_c x^2 + (w_c + h_c) x + 1) = budget
// over the charts (A: area, w x h: minimal box, metres, each scaled by its mesh's
// lightmap_scale), i.e. the charts' areas in texels plus the texels conservative coverage
// adds along their borders. With more charts than half the budget, the budget is taken as
// twice the chart count (every chart needs at least a texel). Returns metres per texel.
double texelSizeForBudget(double area_sum, double perimeter_sum, std::size_t charts, std::uint64_t budget);

// Per Scene::meshes entry.
struct MeshLightmap {
  std::vector<std::uint32_t> source_vertex;   // new vertex -> original vertex; empty = unchanged
  std::vector<std::uint32_t> triangle_chart;  // per triangle; kNoChart if not generated here
};

// What the precompute needs next to the uv1 on the meshes.
struct LightmapAtlas {
  bool generated = false;        // uv1 generated (true) or every existing one kept (false)
  int resolution = 0;            // texels per side of one page
  int pages = 1;                 // pages stacked along v: the atlas is resolution x height()
  float texel_size_m = 0.0f;     // metres per texel
  int gutter_texels = 0;
  std::uint32_t chart_count = 0;
  std::vector<MeshLightmap> meshes;  // parallel to Scene::meshes
  std::vector<std::uint32_t> probe_lit;  // static meshes lit from the volume (Scene::meshes index)

  int height() const { return resolution * pages; }
};

struct UnwrapResult {
  LightmapAtlas atlas;
  UnwrapReport report;
};

Expected<UnwrapResult> unwrap(scene::Scene& scene, const UnwrapOptions& options);

}  // namespace lightlink::charts
