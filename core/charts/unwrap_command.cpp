#include "core/charts/unwrap_command.h"

#include <fstream>

#include <nlohmann/json.hpp>

#include "core/charts/gltf_writer.h"
#include "core/charts/preview_png.h"
#include "core/scene/load.h"

namespace lightlink::charts {

Expected<UnwrapReport> runUnwrap(const UnwrapCommand& command) {
  if (Status s = validate(command.options); !s) return s;
  scene::LoadOptions load_options;
  load_options.load_textures = false;  // geometry only: textures are copied, never decoded
  load_options.files = command.files;
  Expected<scene::Scene> scene = scene::loadScene(command.input_path, load_options);
  if (!scene) return scene.status();
  Expected<UnwrapResult> result = unwrap(*scene, command.options);
  if (!result) return result.status();
  if (!command.output_path.empty()) {
    if (Status s = writeGltfWithLightmapUv(command.input_path, *scene, result->atlas, command.output_path,
                                           command.files);
        !s)
      return s;
  }
  if (!command.preview_png.empty()) {
    if (Status s = writeChartPreviewPng(*scene, result->atlas, command.preview_png); !s) return s;
  }
  if (!command.report_json.empty()) {
    std::ofstream out(command.report_json, std::ios::binary | std::ios::trunc);
    out << result->report.toJson().dump(2) << '\n';
    if (!out) return ioError("unwrap: cannot write report '{}'", command.report_json);
  }
  return result->report;
}

}  // namespace lightlink::charts
