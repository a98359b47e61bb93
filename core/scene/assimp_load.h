// OBJ (+MTL) and FBX ingest through assimp, producing the same Scene as loadGltf with the
// same promises: every file read goes through SceneFiles (the .mtl and textures stay
// inside the scene's folder unless FileAccess allows outside), the LoadOptions budgets
// hold, and bad data is an error naming the file, the object (OBJ object/group, FBX node)
// and the field; degenerate triangles are dropped with a count and a warning.
//
// Conventions: OBJ has no unit, so 1 unit is read as 1 metre; FBX is converted to metres
// by its UnitScaleFactor (centimetres per unit). Axes are kept as stored. Materials
// map MTL keys (and FBX's equivalents, through assimp's common keys) onto glTF's model:
// Kd -> baseColorFactor.rgb, d (or 1 - Tr) -> baseColorFactor.a, map_Kd -> base colour
// texture, Ke -> emissive (split into factor <= 1 and strength), map_Ke -> emissive
// texture; everything is static, metallic 0, roughness 1. A missing or undecodable texture
// is a warning and the factor alone applies. The file's lights and cameras are not read.
#pragma once

#include <string>

#include "core/common/status.h"
#include "core/scene/load.h"
#include "core/scene/scene.h"

namespace lightlink::scene {

// `path` must end in .obj or .fbx (case-insensitive).
Expected<Scene> loadWithAssimp(const std::string& path, const LoadOptions& options = {});

}  // namespace lightlink::scene
