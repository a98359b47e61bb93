// Internal to core/scene: KHR_lights_punctual lights, validated (finite, non-negative
// intensity/range/colour, spot cones inside the spec's limits) and placed by the nodes
// that reference them: position = node world translation, direction = node world -Z.
#pragma once

#include <vector>

#include "core/scene/gltf_context.h"
#include "core/scene/gltf_nodes.h"

namespace lightlink::scene::gltf {

Status loadLights(const Context& ctx, const std::vector<PlacedNode>& nodes);

}  // namespace lightlink::scene::gltf
