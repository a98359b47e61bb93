// The description of a bake's lighting files that the lightmapped glTF carries as its root
// LIGHTLINK_lighting extension (docs/outputs.md, "The glTF and its lighting"): which file
// holds what, the SH convention and normalisation, the units, and the grid's origin,
// spacing, dims and validity, so an engine finds everything from the glTF alone.
#pragma once

#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "core/caches/caches.h"
#include "core/relight/relight.h"

namespace lightlink::output {

// Names (relative to the glTF) of what the bake wrote (EXR layout 2, docs/outputs.md);
// empty = not written.
struct LightingFiles {
  std::string encoding = "l2";           // l0 | l1 | l2
  std::vector<std::string> lightmap_sh;  // lightmap_<c>.exr, in SH index order (none for L0)
  std::string direct, valid, direct_valid;
  std::string irradiance;                // the plain RGB L0 map bound through MOZ_lightmap
  std::vector<std::string> grid_sh;      // grid_<c>.exr, in SH index order
  std::string grid_valid, grid_json, grid_raw, grid_threejs;

  // Sorts a bake's file names into the fields above.
  static LightingFiles fromWritten(const std::vector<std::string>& names, std::string encoding);
};

// `grid` is null when the bake has no grid.
nlohmann::json describeLighting(const relight::RelightResult& result, const caches::GridCaches* grid,
                                const LightingFiles& files, int lightmap_texcoord = 1);

}  // namespace lightlink::output
