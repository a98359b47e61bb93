#include "clients/client/result_files.h"

#include <filesystem>
#include <optional>

#include "clients/client/core_bridge.h"
#include "core/output/grid_threejs.h"
#include "core/output/lighting_description.h"
#include "core/output/output.h"

namespace lightlink::client {

Expected<ResultFiles> writeResultFiles(const Textures& tex, const std::string& dir, const ResultFileOptions& options) {
  namespace fs = std::filesystem;
  const fs::path out(dir);
  auto result = toRelightResult(tex);
  if (!result) return result.status();
  output::ExrOptions exr;
  exr.half = options.half;
  exr.scene_hash = options.scene_hash;
  exr.encoding = options.encoding;
  exr.compress = options.compress;
  exr.irradiance = options.irradiance;
  const caches::LightmapCaches preview = previewCachesOf(tex);
  auto lm = output::writeLightmapExrs(*result, preview, out.string(), exr);
  if (!lm) return lm.status();
  ResultFiles written;
  written.files = lm->files;
  if (options.png_preview) {
    if (Status s = output::writeIrradiancePng(*result, preview, (out / "lightmap.png").string()); !s) return s;
    written.files.push_back("lightmap.png");
  }
  std::optional<caches::GridCaches> grid;
  if (tex.info.has_grid && tex.has(Payload::kGridSh)) {
    auto g = gridCachesOf(tex);
    if (!g) return g.status();
    grid = std::move(g).value();
    if (Status s = output::writeGridRaw(*result, *grid, (out / "grid.raw").string(), options.encoding); !s) return s;
    if (options.all_grid_files) {
      auto files = output::writeGridExrs(*result, *grid, out.string(), exr);
      if (!files) return files.status();
      if (Status s = output::writeGridJson(*result, *grid, (out / "grid.json").string(), options.encoding); !s) return s;
      if (Status s = output::writeThreeJsGrid(*result, *grid, (out / "grid_threejs.json").string(), "grid_threejs.bin");
          !s)
        return s;
      written.files.insert(written.files.end(), files->files.begin(), files->files.end());
      written.files.insert(written.files.end(), {"grid.json", "grid_threejs.json", "grid_threejs.bin"});
    }
    written.files.push_back("grid.raw");
  }
  const output::LightingFiles names =
      output::LightingFiles::fromWritten(written.files, std::string(output::encodingName(options.encoding)));
  written.lighting = output::describeLighting(*result, grid ? &*grid : nullptr, names);
  return written;
}

}  // namespace lightlink::client
