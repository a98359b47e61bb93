// The description of a bake's lighting files that the lightmapped glTF carries as its root
// LIGHTLINK_lighting extension (docs/outputs.md, "The glTF and its lighting"): which file
// holds what, the SH convention and normalisation, the units, and the grid's origin,
// spacing, dims and validity, so an engine finds everything from the glTF alone.
#pragma once

#include <string>

#include <nlohmann/json.hpp>

#include "core/caches/caches.h"
#include "core/relight/relight.h"

namespace lightlink::output {

// Names (relative to the glTF) of what the bake wrote; empty = not written.
struct LightingFiles {
  std::string lightmap = "lightmap.exr";
  std::string direct;      // direct.exr, when the direct layer is finer than the lightmap
  std::string irradiance;  // the plain RGB L0 map bound through MOZ_lightmap
  std::string grid_exr, grid_json, grid_raw, grid_threejs;
};

// `grid` is null when the bake has no grid.
nlohmann::json describeLighting(const relight::RelightResult& result, const caches::GridCaches* grid,
                                const LightingFiles& files, int lightmap_texcoord = 1);

}  // namespace lightlink::output
