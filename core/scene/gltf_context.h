// Internal to core/scene: the state shared by the glTF ingest steps (structure checks,
// node flattening, primitives, materials, lights) and the naming helpers that make every
// message say which file and which glTF object it is about, e.g.
// "scene.gltf: mesh 2 'Floor' primitive 0 accessor 5 (POSITION): ...".
#pragma once

#include <string>
#include <string_view>

#include <tiny_gltf.h>

#include "core/common/status.h"
#include "core/scene/lighting_images.h"
#include "core/scene/load.h"
#include "core/scene/scene.h"

namespace lightlink::scene::gltf {

struct Context {
  std::string file;  // the path as given, prefixed to every message
  const tinygltf::Model& model;
  Scene& scene;
  const LoadOptions& options;
  LightingImages lighting = {};  // which textures and images feed lighting

  Status invalid(std::string_view object, std::string_view what) const {
    return {Code::kInvalidInput, fmt::format("{}: {}: {}", file, object, what)};
  }
  Status unsupported(std::string_view object, std::string_view what) const {
    return {Code::kUnsupported, fmt::format("{}: {}: {}", file, object, what)};
  }
  void warn(std::string_view object, std::string_view what) const {
    scene.warnings.push_back(fmt::format("{}: {}: {}", file, object, what));
  }
};

// "<kind> <index> '<name>'" or "<kind> <index>" when unnamed.
inline std::string describe(std::string_view kind, int index, const std::string& name) {
  return name.empty() ? fmt::format("{} {}", kind, index)
                      : fmt::format("{} {} '{}'", kind, index, name);
}

inline std::string describeMesh(const tinygltf::Model& model, int mesh) {
  return describe("mesh", mesh, model.meshes[static_cast<std::size_t>(mesh)].name);
}

inline std::string describePrimitive(const tinygltf::Model& model, int mesh, int primitive) {
  return fmt::format("{} primitive {}", describeMesh(model, mesh), primitive);
}

inline std::string describeNode(const tinygltf::Model& model, int node) {
  return describe("node", node, model.nodes[static_cast<std::size_t>(node)].name);
}

}  // namespace lightlink::scene::gltf
