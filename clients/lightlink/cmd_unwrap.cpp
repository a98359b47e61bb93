// `lightlink unwrap`: generate (or check) lightmap UVs and write the glTF back.
#include <cstdio>

#include <nlohmann/json.hpp>

#include "clients/lightlink/commands.h"
#include "clients/lightlink/exit_codes.h"
#include "clients/lightlink/scene_access.h"
#include "core/charts/unwrap_command.h"
#include "core/precompute/precompute.h"

namespace lightlink::cli {

int runUnwrap(const UnwrapArgs& args) {
  charts::UnwrapCommand command;
  command.input_path = args.scene_path;
  command.files = sceneFileAccess(args.allow_outside_scene);
  command.output_path = args.output_path;
  command.preview_png = args.preview_png;
  command.report_json = args.report_json;
  command.options.texel_size_m = args.texel_size_m;
  command.options.resolution = args.resolution;
  command.options.gutter_texels = args.gutter_texels;
  // The same texel budget as precompute and bake (docs/cli.md "Limits").
  command.options.max_texels = precompute::PrecomputeLimits{}.max_texels;
  auto report = charts::runUnwrap(command);
  if (!report) return reportError("unwrap", report.status());
  const std::string text = args.json ? report->toJson().dump(2) + "\n" : report->toText();
  std::fwrite(text.data(), 1, text.size(), stdout);
  return kExitOk;
}

}  // namespace lightlink::cli
