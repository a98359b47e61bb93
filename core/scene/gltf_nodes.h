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
  float lightmap_scale = 1.0f;  // extras.lightlink.lightmap_scale, inherited
  bool probe_lit = false;       // extras.lightlink.lightmap == false, inherited
  int cast_shadows = -1;        // extras.lightlink.cast_shadows, inherited: -1 none (the material decides)
  int contribute_gi = -1;       // extras.lightlink.contribute_gi, inherited: -1 none
  int receive_gi = -1;          // extras.lightlink.receive_gi (ReceiveGi), inherited: -1 none
};

// Nodes of the default scene (scene 0 when `scene` is absent; every root node when the
// file has no scenes) in depth-first order, parents before children.
Expected<std::vector<PlacedNode>> placeNodes(const Context& ctx);

// What a node's extras {"lightlink": {...}} set for itself and its descendants: "static"
// (bool), "lightmap_scale" (number in [1/64, 64]: texel density multiplier), "lightmap"
// (bool; false = indirect light from the irradiance volume, not the lightmap), "cast_shadows"
// (bool; false = shadow rays pass through), "contribute_gi" (bool), "receive_gi" (string).
struct NodeOverrides {
  int is_static = -1;            // -1 none, 0 dynamic, 1 static
  float lightmap_scale = 0.0f;   // 0 = none
  int lightmap = -1;             // -1 none, 0 probe-lit, 1 lightmapped
  int cast_shadows = -1;         // -1 none, 0 no, 1 yes
  int contribute_gi = -1;        // -1 none, 0 no, 1 yes
  int receive_gi = -1;           // -1 none, else ReceiveGi
};

// extras.lightlink.receive_gi's value: "lightmap", "volume" or "off" (ReceiveGi), or an error
// naming `object`.
Expected<int> parseReceiveGi(const Context& ctx, const std::string& object, const tinygltf::Value& v);
Expected<NodeOverrides> nodeOverrides(const Context& ctx, int node);

}  // namespace lightlink::scene::gltf
