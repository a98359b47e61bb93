// Internal to core/scene: flattens the node hierarchy of the default scene into a list
// of placed nodes (world transform composed parent * child in double precision, static
// flag inherited), rejecting what would make a transform meaningless: non-finite or
// degenerate matrices, malformed TRS, cycles and nodes with two parents.
#pragma once

#include <vector>

#include <glm/glm.hpp>

#include "core/scene/gltf_context.h"

namespace lightlink::scene::gltf {

struct PlacedNode {
  int node = -1;
  glm::dmat4 world_from_node{1.0};
  bool is_static = true;
};

// Nodes of the default scene (scene 0 when `scene` is absent; every root node when the
// file has no scenes) in depth-first order, parents before children.
Expected<std::vector<PlacedNode>> placeNodes(const Context& ctx);

// The lightlink static flag a node sets for itself and its descendants, if any.
Expected<int> staticOverride(const Context& ctx, int node);  // -1 none, 0 dynamic, 1 static

}  // namespace lightlink::scene::gltf
