#include "core/output/lighting_description.h"

#include <algorithm>

#include "core/output/output.h"

namespace lightlink::output {

nlohmann::json describeLighting(const relight::RelightResult& result, const caches::GridCaches* grid,
                                const LightingFiles& files, int lightmap_texcoord) {
  nlohmann::json j;
  j["version"] = 1;
  j["light_set_version"] = result.version;
  j["docs"] = "lightlink docs/outputs.md, docs/sh.md, docs/units.md";
  j["units"] = {{"irradiance", "lux per linear RGB channel"},
                {"radiance_sh", "cd/m^2 per linear RGB channel (irradiance / pi sr)"},
                {"length", "m"}};
  nlohmann::json layers = nlohmann::json::array();
  for (int i = 0; i < result.coeffCount(); ++i) layers.push_back(shLayerName(i));
  j["sh"] = {{"bands", result.bands},
             {"basis", "real orthonormal SH without the Condon-Shortley phase, i = l*l + l + m, band 1 = (y, z, x)"},
             {"stores", "radiance: plain projections, nothing pre-scaled (constant radiance L gives L00 = sqrt(4 pi) L)"},
             {"irradiance", "E(n) = max(0, sum_i A_l L_i Y_i(n)), A_l = pi, 2 pi / 3, pi / 4, 0"},
             {"layers", layers}};
  nlohmann::json lightmap = {{"uri", files.lightmap},
                             {"texCoord", lightmap_texcoord},
                             {"width", result.width},
                             {"height", result.height},
                             {"channels", "<layer>.R, <layer>.G, <layer>.B per SH layer; valid.Y = 1 where a texel holds a value"},
                             {"row0", "v = 0 (top)"}};
  if (!files.direct.empty()) {
    lightmap["direct"] = {{"uri", files.direct},
                          {"width", result.direct_width},
                          {"height", result.direct_height},
                          {"channels", "direct.R, direct.G, direct.B (baked direct irradiance, lux)"}};
  } else {
    lightmap["direct"] = {{"uri", files.lightmap}, {"channels", "direct.R, direct.G, direct.B (baked direct irradiance, lux)"}};
  }
  j["lightmap"] = std::move(lightmap);
  if (!files.irradiance.empty())
    j["irradiance"] = {{"uri", files.irradiance},
                       {"texCoord", lightmap_texcoord},
                       {"what", "L0: irradiance for the surface's normal, plain R, G, B"},
                       {"bound_by", "MOZ_lightmap"}};
  if (grid && grid->size() > 0) {
    nlohmann::json g = {{"origin_m", {grid->origin.x, grid->origin.y, grid->origin.z}},
                        {"spacing_m", grid->spacing_m},
                        {"dims", {grid->dims.x, grid->dims.y, grid->dims.z}},
                        {"index", "(z * dims[1] + y) * dims[0] + x; world = origin_m + spacing_m * (x, y, z)"},
                        {"valid_count", grid->validCount()}};
    if (!files.grid_exr.empty())
      g["exr"] = {{"uri", files.grid_exr}, {"atlas", "slice z at pixel x offset z * dims[0], pixel row = y"},
                  {"validity", "valid.Y"}};
    if (!files.grid_json.empty()) g["json"] = {{"uri", files.grid_json}, {"validity", "valid (one 0/1 per point)"}};
    if (!files.grid_raw.empty()) g["raw"] = {{"uri", files.grid_raw}, {"layout", "docs/outputs.md, Grid"}};
    if (!files.grid_threejs.empty())
      g["threejs"] = {{"uri", files.grid_threejs}, {"for", "three.js LightProbeGrid / LightProbeGridWebGL"}};
    j["grid"] = std::move(g);
  }
  return j;
}

}  // namespace lightlink::output
