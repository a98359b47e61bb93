// writeResultFiles: one received result (Textures) as the files a bake writes (EXR layout 2,
// grid.json/.raw, the three.js grid) plus the LIGHTLINK_lighting description of them, so
// readers of a bake folder read a daemon's result the same way. `lightlink pull` writes a
// folder with it; the web gateway (clients/gateway) one folder per live version.
#pragma once

#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "clients/client/textures.h"
#include "core/common/status.h"
#include "core/output/encoding.h"

namespace lightlink::client {

struct ResultFileOptions {
  output::Encoding encoding = output::Encoding::kL2;
  bool half = true;          // false: float EXRs
  bool png_preview = true;   // lightmap.png
  std::string scene_hash;    // the scene's cache key (hex), into every file's header
  bool compress = true;      // false: uncompressed EXRs (output::ExrOptions::compress)
  bool irradiance = true;    // false: no irradiance.exr beside SH files (output::ExrOptions::irradiance)
  // false: of the grid only grid.raw (what the web viewer reads), not its EXRs, grid.json
  // and the three.js files.
  bool all_grid_files = true;
};

struct ResultFiles {
  std::vector<std::string> files;  // names in the folder, in writing order
  // The glTF LIGHTLINK_lighting extension's object for these files (docs/outputs.md).
  nlohmann::json lighting;
};

// Writes into `dir` (which must exist). The wire carries no surface normals: irradiance.exr
// and the preview evaluate the SH at each texel's dominant light direction
// (previewCachesOf), an approximation; the SH files are exact.
Expected<ResultFiles> writeResultFiles(const Textures& textures, const std::string& dir, const ResultFileOptions& options);

}  // namespace lightlink::client
