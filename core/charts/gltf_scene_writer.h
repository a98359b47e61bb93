// Writes a Scene as a fresh glTF 2.0 file, for inputs that are not glTF (OBJ, FBX): there is
// no source glTF to edit, so the lightmapped scene is built from what was loaded. One node
// per MeshInstance, in Scene order, with no transform (positions and normals are already in
// world space, in metres); each carries POSITION, NORMAL, TEXCOORD_0 (the mesh's uv0, or the
// lightmap uv when it has none: glTF's sets start at 0), TEXCOORD_1 (the lightmap uv) and
// 16- or 32-bit indices. Materials keep baseColorFactor,
// emissiveFactor (with KHR_materials_emissive_strength above 1), metallic/roughness and
// doubleSided; a base colour or emissive texture read from a file is referenced by its
// name and the file copied next to the output (an embedded FBX image is left out, the
// factor stays). Loading the output with loadGltf gives the same meshes in the same order.
#pragma once

#include <string>
#include <vector>

#include "core/charts/gltf_lighting.h"
#include "core/common/status.h"
#include "core/scene/scene.h"
#include "core/scene/scene_files.h"

namespace lightlink::charts {

// `in_path` is the scene file the Scene was loaded from (its textures are read under
// `access`); the output is .gltf (+ a .bin named after it) or .glb by `out_path`'s extension.
// `lightmapped` (parallel to scene.meshes, or empty: none) says which meshes `lighting`'s
// MOZ_lightmap binds.
Status writeGltfFromScene(const std::string& in_path, const scene::Scene& scene, const std::string& out_path,
                          const scene::FileAccess& access = {}, const GltfLighting& lighting = {},
                          const std::vector<bool>& lightmapped = {});

}  // namespace lightlink::charts
