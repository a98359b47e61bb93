// The `lightlink unwrap` command as a function, so the CLI (and the service later) stay
// thin: load a glTF, generate or check its lightmap uv, write the glTF back with
// TEXCOORD_1, optionally the chart preview PNG and the JSON report. The report is
// returned for printing (UnwrapReport::toText).
#pragma once

#include <string>

#include "core/charts/unwrap.h"
#include "core/common/status.h"
#include "core/scene/scene_files.h"

namespace lightlink::charts {

struct UnwrapCommand {
  std::string input_path;    // .gltf or .glb
  std::string output_path;   // .gltf or .glb; empty = do not write a glTF
  std::string preview_png;   // empty = no preview
  std::string report_json;   // empty = no JSON file
  UnwrapOptions options;
  scene::FileAccess files;   // which files the scene may name (default: its own folder only)
};

Expected<UnwrapReport> runUnwrap(const UnwrapCommand& command);

}  // namespace lightlink::charts
