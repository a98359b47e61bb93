// `lightlink inspect`: load + validate a scene, print what lightlink will work with.
#include <cstdio>
#include <fstream>
#include <iterator>

#include "clients/lightlink/commands.h"
#include "clients/lightlink/exit_codes.h"
#include "clients/lightlink/scene_access.h"
#include "clients/lightlink/scene_summary.h"
#include "core/scene/load.h"
#include "core/scene/surface_rules.h"

namespace lightlink::cli {

int runInspect(const InspectArgs& args) {
  scene::LoadOptions load;
  load.files = sceneFileAccess(args.allow_outside_scene);
  auto scene = scene::loadScene(args.scene_path, load);
  if (!scene) return reportError("inspect", scene.status());
  if (!args.surfaces_path.empty()) {
    std::ifstream in(args.surfaces_path, std::ios::binary);
    if (!in) return reportError("inspect", ioError("cannot open surface rules '{}'", args.surfaces_path));
    const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    auto rules = scene::parseSurfaceRules(text, args.surfaces_path);
    if (!rules) return reportError("inspect", rules.status());
    scene::applySurfaceRules(*scene, *rules);
  }
  const auto summary = summarizeScene(*scene);
  const std::string text = args.json ? summary.dump(2) + "\n" : formatSummary(summary);
  std::fwrite(text.data(), 1, text.size(), stdout);
  return kExitOk;
}

}  // namespace lightlink::cli
