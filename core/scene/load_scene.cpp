#include <algorithm>
#include <cctype>
#include <filesystem>

#include "core/scene/assimp_load.h"
#include "core/scene/load.h"

namespace lightlink::scene {
namespace {

std::string lowerExtension(const std::string& path) {
  std::string ext = std::filesystem::path(path).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return ext;
}

}  // namespace

const char* acceptedSceneExtensions() { return "'.gltf', '.glb', '.obj' (with its .mtl), '.fbx'"; }

bool isAssimpScenePath(const std::string& path) {
  const std::string ext = lowerExtension(path);
  return ext == ".obj" || ext == ".fbx";
}

Expected<Scene> loadScene(const std::string& path, const LoadOptions& options) {
  const std::string ext = lowerExtension(path);
  if (isAssimpScenePath(path)) return loadWithAssimp(path, options);
  // Anything else goes to the glTF reader, which tells glTF by its content (the daemon
  // stages uploaded glTF bytes under a temporary name) and otherwise fails listing the
  // accepted extensions.
  return loadGltf(path, options);
}

}  // namespace lightlink::scene
