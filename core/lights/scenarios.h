// Lighting scenarios: named light sets over one precomputation (day, night, door open), and
// their blend. Light transport is linear in what emits, so the lighting of a weighted blend of
// scenarios is the same weighted blend of each scenario's lighting: an engine blends baked
// scenarios texel by texel (docs/outputs.md "Lighting scenarios"), and the daemon blends them
// by relighting one light set that holds every scenario's lights at its weight.
//
// Names are what a designer types and what bake uses as a folder name, so they are kept to
// letters, digits, '_', '-' and '.' (1-64 characters, not starting with '.').
#pragma once

#include <span>
#include <string>
#include <string_view>
#include <vector>

#include <glm/glm.hpp>

#include "core/common/status.h"
#include "core/lights/light_set.h"

namespace lightlink::lights {

inline constexpr std::size_t kMaxScenarios = 64;
// A blend weight beyond this is a typing mistake, not a scenario's share.
inline constexpr float kMaxScenarioWeight = 1e3f;

struct Scenario {
  std::string name;
  LightSet lights;
};

struct ScenarioWeight {
  std::string name;
  float weight = 1.0f;
};

// A material's own emission, which the blend needs to add a scaled emission to a constant
// radiance (EmissiveOverride::kRadiance replaces the texture, kScale multiplies it).
struct MaterialEmission {
  glm::vec3 radiance{0.0f};   // emissive factor * strength, linear RGB
  bool textured = false;      // an emissive texture modulates it
};

// Checks a scenario name (the rule above); `what` names it in the message.
Status validateScenarioName(std::string_view name, std::string_view what = "scenario");

// Parses "name=weight" ("day=0.25"); a bare "name" is weight 1.
Expected<ScenarioWeight> parseScenarioWeight(std::string_view text);

// The light set whose lighting is sum_k w_k * lighting(scenario k):
//  - punctual lights: every light of a scenario with w > 0, intensity times w. With one
//    scenario at w > 0 the ids stay; with several they become "<scenario>/<id>".
//  - emission: per material, the weighted sum of each scenario's emission (its override, or
//    the material's own). Scale overrides blend as scales; where one scenario sets a constant
//    radiance, the others' emission must be a constant too (an untextured material), else the
//    blend cannot be one override and it is an error naming the material.
//  - sky: the weighted sum of the skies' radiance SH (uniform radiance when no sky has SH).
//  - emissive_baked must be the same in every scenario.
// Weights: finite, in [0, kMaxScenarioWeight]; names: known, each at most once.
Expected<LightSet> blendScenarios(std::span<const Scenario> scenarios, std::span<const ScenarioWeight> weights,
                                  std::span<const MaterialEmission> materials);

}  // namespace lightlink::lights
