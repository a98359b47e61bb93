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
// Existing TEXCOORD_1: if `keep_existing_uv1` and every static mesh has one, all are kept
// bit-exactly and only checked (overlaps, flips, out of [0,1]: report warnings). If some
// static meshes lack it, uv1 is regenerated for all static meshes (one consistent atlas;
// a warning names the meshes whose uv1 was replaced). Dynamic meshes are never touched.
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

struct UnwrapOptions {
  // Metres of surface per texel. Unset: the smallest size at which all charts fit into
  // `resolution` (or `target_resolution` when that is unset too).
  std::optional<float> texel_size_m;
  // Atlas width = height in texels. Unset: `target_resolution` if the texel size is also
  // unset, else the smallest power of two that fits.
  std::optional<int> resolution;
  int target_resolution = 1024;
  int gutter_texels = 2;            // empty texels between charts and at the atlas border
  float normal_cone_deg = 60.0f;    // charting: max face normal deviation from the chart normal
  float hard_edge_deg = 60.0f;      // charting: dihedral angle that always cuts charts
  float planar_deg = 5.0f;          // flattening: charts flatter than this are projected
  float max_stretch = 2.0f;         // flattening: per-triangle area stretch limit (> 1)
  float min_chart_fill = 0.5f;      // flattening: charts (8+ faces) covering less of their
                                    // minimal box are split (curved strips pack badly)
  float weld_tolerance = 1e-6f;     // weld distance as a fraction of Scene::scale
  bool keep_existing_uv1 = true;
  // Most texels the atlas may have (width x height), checked before any packing; 0 = no
  // limit. Over it: Code::kResourceExhausted naming the limit.
  std::uint64_t max_texels = 0;
  // Polled for cancellation only (Progress::cancelled); a cancelled unwrap returns kCancelled.
  const Progress* progress = nullptr;
};

// Checks ranges; the message names the option and the accepted range.
Status validate(const UnwrapOptions& options);

// Per Scene::meshes entry.
struct MeshLightmap {
  std::vector<std::uint32_t> source_vertex;   // new vertex -> original vertex; empty = unchanged
  std::vector<std::uint32_t> triangle_chart;  // per triangle; kNoChart if not generated here
};

// What the precompute needs next to the uv1 on the meshes.
struct LightmapAtlas {
  bool generated = false;        // uv1 generated (true) or every existing one kept (false)
  int resolution = 0;            // texels per side
  float texel_size_m = 0.0f;     // metres per texel
  int gutter_texels = 0;
  std::uint32_t chart_count = 0;
  std::vector<MeshLightmap> meshes;  // parallel to Scene::meshes
};

struct UnwrapResult {
  LightmapAtlas atlas;
  UnwrapReport report;
};

Expected<UnwrapResult> unwrap(scene::Scene& scene, const UnwrapOptions& options);

}  // namespace lightlink::charts
