// Light: one punctual light (KHR_lights_punctual), the value scene ingest reads from glTF and
// a LightSet (core/lights/light_set.h) carries to the relight.
//
// It lives in core/lights rather than core/scene so that the light-set schema and its
// validator build without the scene loaders (tinygltf, assimp): the client library links
// them. Units are those of docs/units.md; scene.h names it scene::Light.
#pragma once

#include <string>

#include <glm/glm.hpp>

#include "core/common/enum_names.h"

namespace lightlink::lights {

// KHR_lights_punctual, in world space.
struct Light {
  enum class Kind { kPoint, kSpot, kDirectional };
  std::string name;
  Kind kind = Kind::kPoint;
  int gltf_node = -1;
  glm::vec3 color{1.0f};  // linear RGB, multiplies intensity
  // Point/spot: luminous intensity in candela (lm/sr). Directional: illuminance in lux.
  float intensity = 1.0f;
  float range = 0.0f;     // metres; 0 = infinite (glTF: undefined)
  float inner_cone_angle = 0.0f;                  // radians, spot only
  float outer_cone_angle = 0.78539816339744831f;  // radians, spot only (glTF default pi/4)
  glm::vec3 position{0.0f};      // world, point/spot
  glm::vec3 direction{0, 0, -1}; // world, unit: the direction light travels (spot/directional)
};

// The light-set JSON "type" names (docs/lightset.md), the one spelling of Light::Kind.
inline constexpr EnumNames<Light::Kind, 3> kLightKindNames{{
    {"point", Light::Kind::kPoint},
    {"spot", Light::Kind::kSpot},
    {"directional", Light::Kind::kDirectional},
}};

}  // namespace lightlink::lights
