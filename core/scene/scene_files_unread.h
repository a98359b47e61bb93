// Internal to core/scene: the loader's file access (SceneFiles::install) with some files
// left unread. An image nothing lightlink computes reads (a normal map, an unused image;
// lighting_images.h) is not read from disk at all: tinygltf is told it exists and is handed
// a one-byte stand-in, which the image loader never decodes. So such a file costs no I/O,
// and a missing one is no warning.
#pragma once

#include <filesystem>
#include <vector>

#include "core/scene/scene_files.h"

namespace lightlink::scene {

struct UnreadFiles {
  const SceneFiles* files = nullptr;
  std::vector<std::filesystem::path> unread;  // canonical paths, as SceneFiles::resolveUri gives them
};

// As files.install(loader), but the paths in `access.unread` are never opened. `access`
// must outlive the loads.
void installSkippingUnread(const UnreadFiles& access, tinygltf::TinyGLTF& loader);

}  // namespace lightlink::scene
