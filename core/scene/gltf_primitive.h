// Internal to core/scene: turns one glTF primitive placed by one node into a
// MeshInstance in world space — attributes read through checked accessors, strips and
// fans triangulated, indices range-checked, winding flipped under mirror transforms,
// normals transformed by the inverse transpose or generated. Degenerate triangles are
// left for the caller to drop once the scene scale is known. Expects Scene::materials to
// be loaded already (it warns when a material's texture reads a TEXCOORD set the
// primitive lacks).
#pragma once

#include "core/scene/gltf_context.h"
#include "core/scene/gltf_nodes.h"

namespace lightlink::scene::gltf {

Expected<MeshInstance> buildInstance(const Context& ctx, const PlacedNode& placed, int mesh,
                                     int primitive);

}  // namespace lightlink::scene::gltf
