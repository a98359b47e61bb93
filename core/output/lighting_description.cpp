#include "core/output/lighting_description.h"

#include <algorithm>

#include "core/output/output.h"

namespace lightlink::output {

LightingFiles LightingFiles::fromWritten(const std::vector<std::string>& names, std::string encoding) {
  LightingFiles f;
  f.encoding = std::move(encoding);
  const auto has = [&](const std::string& n) { return std::find(names.begin(), names.end(), n) != names.end(); };
  for (int i = 0; i < 16; ++i) {
    if (has("lightmap_" + shLayerName(i) + ".exr")) f.lightmap_sh.push_back("lightmap_" + shLayerName(i) + ".exr");
    if (has("grid_" + shLayerName(i) + ".exr")) f.grid_sh.push_back("grid_" + shLayerName(i) + ".exr");
  }
  for (auto [field, name] : {std::pair{&f.direct, "direct.exr"}, {&f.valid, "valid.exr"},
                             {&f.direct_valid, "direct_valid.exr"}, {&f.irradiance, "irradiance.exr"},
                             {&f.grid_valid, "grid_valid.exr"}, {&f.grid_json, "grid.json"}, {&f.grid_raw, "grid.raw"},
                             {&f.grid_threejs, "grid_threejs.json"}})
    if (has(name)) *field = name;
  return f;
}

nlohmann::json describeLighting(const relight::RelightResult& result, const caches::GridCaches* grid,
                                const LightingFiles& files, int lightmap_texcoord) {
  nlohmann::json j;
  j["version"] = 2;
  j["exr_layout"] = kExrLayout;
  j["encoding"] = files.encoding;
  j["light_set_version"] = result.version;
  j["docs"] = "lightlink docs/outputs.md, docs/sh.md, docs/units.md";
  j["units"] = {{"irradiance", "lux per linear RGB channel"},
                {"radiance_sh", "cd/m^2 per linear RGB channel (irradiance / pi sr)"},
                {"length", "m"}};
  j["sh"] = {{"basis", "real orthonormal SH without the Condon-Shortley phase, i = l*l + l + m, band 1 = (y, z, x)"},
             {"stores", "radiance: plain projections, nothing pre-scaled (constant radiance L gives L00 = sqrt(4 pi) L)"},
             {"irradiance", "E(n) = max(0, sum_i A_l L_i Y_i(n)), A_l = pi, 2 pi / 3, pi / 4, 0"}};
  nlohmann::json lightmap = {{"texCoord", lightmap_texcoord},
                             {"width", result.width},
                             {"height", result.height},
                             {"channels", "R, G, B per file (valid: Y = 1 where a texel holds a value)"},
                             {"row0", "v = 0 (top)"},
                             {"sh", files.lightmap_sh}};
  if (!files.valid.empty()) lightmap["valid"] = files.valid;
  if (!files.direct.empty()) {
    lightmap["direct"] = {{"uri", files.direct}, {"what", "baked direct irradiance, lux"}};
    if (!files.direct_valid.empty())
      lightmap["direct"].update({{"width", result.direct_width},
                                 {"height", result.direct_height},
                                 {"valid", files.direct_valid}});
  }
  j["lightmap"] = std::move(lightmap);
  if (!files.irradiance.empty())
    j["irradiance"] = {{"uri", files.irradiance},
                       {"texCoord", lightmap_texcoord},
                       {"what", "L0: irradiance for the surface's normal (indirect + baked direct), plain R, G, B"},
                       {"bound_by", "MOZ_lightmap"}};
  if (grid && grid->size() > 0) {
    nlohmann::json g = {{"origin_m", {grid->origin.x, grid->origin.y, grid->origin.z}},
                        {"spacing_m", grid->spacing_m},
                        {"dims", {grid->dims.x, grid->dims.y, grid->dims.z}},
                        {"index", "(z * dims[1] + y) * dims[0] + x; world = origin_m + spacing_m * (x, y, z)"},
                        {"valid_count", grid->validCount()}};
    if (!files.grid_sh.empty())
      g["exr"] = {{"sh", files.grid_sh}, {"atlas", "slice z at pixel x offset z * dims[0], pixel row = y"},
                  {"valid", files.grid_valid}};
    if (!files.grid_json.empty()) g["json"] = {{"uri", files.grid_json}, {"validity", "valid (one 0/1 per point)"}};
    if (!files.grid_raw.empty()) g["raw"] = {{"uri", files.grid_raw}, {"layout", "docs/outputs.md, Grid"}};
    if (!files.grid_threejs.empty())
      g["threejs"] = {{"uri", files.grid_threejs}, {"for", "three.js LightProbeGrid / LightProbeGridWebGL"}};
    j["grid"] = std::move(g);
  }
  return j;
}

}  // namespace lightlink::output
