// `lightlink inspect`: load + validate a scene, print what lightlink will work with.
#include <cstdio>

#include "clients/lightlink/commands.h"
#include "clients/lightlink/exit_codes.h"
#include "clients/lightlink/scene_access.h"
#include "clients/lightlink/scene_summary.h"
#include "core/scene/load.h"

namespace lightlink::cli {

int runInspect(const InspectArgs& args) {
  scene::LoadOptions load;
  load.files = sceneFileAccess(args.allow_outside_scene);
  auto scene = scene::loadScene(args.scene_path, load);
  if (!scene) return reportError("inspect", scene.status());
  const auto summary = summarizeScene(*scene);
  const std::string text = args.json ? summary.dump(2) + "\n" : formatSummary(summary);
  std::fwrite(text.data(), 1, text.size(), stdout);
  return kExitOk;
}

}  // namespace lightlink::cli
