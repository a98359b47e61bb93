// Scene ingest. loadScene picks the reader by extension; loadGltf below is the glTF one.
// glTF ingest: loads .gltf/.glb through tinygltf, validates everything lightlink relies
// on, and produces a Scene. Any problem that makes the data unusable is a Status naming
// the file, the object (mesh/primitive/accessor index and name) and what is wrong;
// recoverable oddities (degenerate triangles, unknown optional extensions) become
// Scene::warnings. Every file the scene names is read through SceneFiles (scene_files.h).
#pragma once

#include <cstdint>
#include <string>

#include "core/common/status.h"
#include "core/scene/scene.h"
#include "core/scene/scene_files.h"

namespace lightlink::scene {

struct LoadOptions {
  bool load_textures = true;  // decode base colour / emissive images for CPU sampling (false: read no image)
  FileAccess files;           // buffer and image URIs stay inside the scene's folder by default
  // Budgets, each checked before the work it bounds; over one, loadGltf fails with
  // Code::kResourceExhausted naming the limit and the value (docs/cli.md "Limits"). 0 = none.
  // Pixels of one image, read from its header before it is decoded (a decompression bomb
  // of a few KB can claim 30000 x 30000).
  std::uint64_t max_image_pixels = std::uint64_t(8192) * 8192;
  // Bytes all decoded images take (RGB8, or RGBA8 where alpha matters; only the images
  // lighting reads are decoded, core/scene/lighting_images.h).
  std::uint64_t max_image_bytes = std::uint64_t(2) << 30;
  // Triangles after instancing, counted from the node graph before any mesh is flattened.
  std::uint64_t max_triangles = 20'000'000;
  // KHR_lights_punctual lights the node graph places.
  std::uint64_t max_lights = 4096;
};

Expected<Scene> loadGltf(const std::string& path, const LoadOptions& options = {});

// The one entry point for a scene file, by its extension (case-insensitive): .gltf/.glb
// -> loadGltf, .obj/.fbx -> assimp (assimp_load.h); any other name is read as glTF if its
// content is glTF (a .glb magic or JSON) and is otherwise Code::kUnsupported naming the
// accepted extensions. Same options and promises for every format.
Expected<Scene> loadScene(const std::string& path, const LoadOptions& options = {});

// True for the extensions loadScene reads through assimp (.obj, .fbx): a scene written
// back from them is a fresh glTF, not an edit of the input.
bool isAssimpScenePath(const std::string& path);

// "'.gltf', '.glb', '.obj', '.fbx'", for messages.
const char* acceptedSceneExtensions();

}  // namespace lightlink::scene
