// How the CLI's scene commands may read the files a scene names: inside the scene's folder
// only, unless --allow-outside-scene was given (core/scene/scene_files.h has the rules).
#pragma once

#include "core/scene/scene_files.h"

namespace lightlink::cli {

inline constexpr const char* kAllowOutsideFlag = "--allow-outside-scene";

inline scene::FileAccess sceneFileAccess(bool allow_outside_scene) {
  scene::FileAccess access;
  access.allow_outside_folder = allow_outside_scene;
  access.outside_hint = "; pass --allow-outside-scene to read it anyway (only for scenes you trust)";
  return access;
}

}  // namespace lightlink::cli
