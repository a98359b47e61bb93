// glTF ingest: loads .gltf/.glb through tinygltf, validates everything lightlink relies
// on, and produces a Scene. Any problem that makes the data unusable is a Status naming
// the file, the object (mesh/primitive/accessor index and name) and what is wrong;
// recoverable oddities (degenerate triangles, unknown optional extensions) become
// Scene::warnings. Every file the scene names is read through SceneFiles (scene_files.h).
#pragma once

#include <string>

#include "core/common/status.h"
#include "core/scene/scene.h"
#include "core/scene/scene_files.h"

namespace lightlink::scene {

struct LoadOptions {
  bool load_textures = true;  // decode base colour / emissive images for CPU sampling
  FileAccess files;           // buffer and image URIs stay inside the scene's folder by default
};

Expected<Scene> loadGltf(const std::string& path, const LoadOptions& options = {});

}  // namespace lightlink::scene
