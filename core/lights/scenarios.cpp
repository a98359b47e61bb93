#include "core/lights/scenarios.h"

#include <charconv>
#include <cmath>
#include <map>

#include <fmt/format.h>

namespace lightlink::lights {

Status validateScenarioName(std::string_view name, std::string_view what) {
  if (name.empty()) return invalidInput("{}: the name is empty", what);
  if (name.size() > 64) return invalidInput("{} \"{}\": longer than 64 characters", what, name);
  if (name.front() == '.') return invalidInput("{} \"{}\": must not start with '.'", what, name);
  for (const char c : name) {
    const bool ok = (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '_' ||
                    c == '-' || c == '.';
    if (!ok) return invalidInput("{} \"{}\": only letters, digits, '_', '-' and '.' are allowed", what, name);
  }
  return {};
}

Expected<ScenarioWeight> parseScenarioWeight(std::string_view text) {
  ScenarioWeight w;
  const auto eq = text.find('=');
  w.name = std::string(text.substr(0, eq));
  if (Status s = validateScenarioName(w.name); !s) return s;
  if (eq != std::string_view::npos) {
    const std::string value(text.substr(eq + 1));
    // from_chars: no locale, and a trailing junk character is an error rather than ignored.
    const auto [end, ec] = std::from_chars(value.data(), value.data() + value.size(), w.weight);
    if (value.empty() || ec != std::errc() || end != value.data() + value.size())
      return invalidInput("scenario \"{}\": weight \"{}\" is not a number", w.name, value);
  }
  if (!std::isfinite(w.weight) || w.weight < 0.0f || w.weight > kMaxScenarioWeight)
    return invalidInput("scenario \"{}\": weight {} is outside [0, {:g}]", w.name, w.weight, kMaxScenarioWeight);
  return w;
}

namespace {

// One scenario's emission of a material: a scale of the material's own, or a constant.
struct EmissionForm {
  bool constant = false;
  glm::vec3 value{1.0f};
};

EmissionForm formOf(const LightSet& set, int material) {
  for (const EmissiveOverride& e : set.emissive())
    if (e.material == material)
      return {e.mode == EmissiveOverride::Mode::kRadiance, e.value};
  return {};
}

}  // namespace

Expected<LightSet> blendScenarios(std::span<const Scenario> scenarios, std::span<const ScenarioWeight> weights,
                                  std::span<const MaterialEmission> materials) {
  if (weights.empty()) return invalidInput("scenario blend: no scenario named");
  if (weights.size() > kMaxScenarios) return invalidInput("scenario blend: more than {} scenarios", kMaxScenarios);
  struct Term {
    const Scenario* scenario;
    float weight;
  };
  std::vector<Term> terms;
  std::map<std::string, bool> seen;
  for (const ScenarioWeight& w : weights) {
    if (Status s = validateScenarioName(w.name); !s) return s;
    if (!std::isfinite(w.weight) || w.weight < 0.0f || w.weight > kMaxScenarioWeight)
      return invalidInput("scenario \"{}\": weight {} is outside [0, {:g}]", w.name, w.weight, kMaxScenarioWeight);
    if (!seen.emplace(w.name, true).second) return invalidInput("scenario \"{}\": named twice in the blend", w.name);
    const Scenario* found = nullptr;
    for (const Scenario& s : scenarios)
      if (s.name == w.name) found = &s;
    if (!found) return invalidInput("scenario \"{}\": no such scenario", w.name);
    if (Status s = found->lights.checkMaterials(materials.size()); !s)
      return invalidInput("scenario \"{}\": {}", w.name, s.message());
    if (w.weight > 0.0f) terms.push_back({found, w.weight});
  }

  LightSet out;
  if (terms.empty()) {
    // Everything at weight 0: the dark scene (every emitter off), not an error.
    for (std::size_t m = 0; m < materials.size(); ++m)
      if (materials[m].radiance != glm::vec3(0.0f))
        if (Status s = out.setEmissive({static_cast<int>(m), EmissiveOverride::Mode::kScale, glm::vec3(0.0f)}); !s)
          return s;
    return out;
  }

  const bool baked = terms.front().scenario->lights.emissiveBaked();
  for (const Term& t : terms)
    if (t.scenario->lights.emissiveBaked() != baked)
      return invalidInput("scenarios \"{}\" and \"{}\": emissive_baked differs, so they cannot be blended",
                          terms.front().scenario->name, t.scenario->name);
  if (Status s = out.setEmissiveBaked(baked); !s) return s;

  const bool rename = terms.size() > 1;
  for (const Term& t : terms)
    for (LightEntry e : t.scenario->lights.lights()) {
      if (rename) e.id = t.scenario->name + "/" + e.id;
      e.light.intensity *= t.weight;
      if (Status s = out.add(std::move(e)); !s) return invalidInput("scenario \"{}\": {}", t.scenario->name, s.message());
    }

  for (std::size_t m = 0; m < materials.size(); ++m) {
    const int mi = static_cast<int>(m);
    bool any_constant = false, any_override = false;
    for (const Term& t : terms) {
      const EmissionForm f = formOf(t.scenario->lights, mi);
      any_constant |= f.constant;
      any_override |= f.constant || f.value != glm::vec3(1.0f);
    }
    glm::vec3 sum(0.0f);
    if (!any_constant) {
      for (const Term& t : terms) sum += t.weight * formOf(t.scenario->lights, mi).value;
      // A material that emits nothing stays untouched; one whose blended scale is 1 needs none.
      if (materials[m].radiance == glm::vec3(0.0f) && !any_override) continue;
      if (sum == glm::vec3(1.0f)) continue;
      if (Status s = out.setEmissive({mi, EmissiveOverride::Mode::kScale, sum}); !s) return s;
      continue;
    }
    for (const Term& t : terms) {
      const EmissionForm f = formOf(t.scenario->lights, mi);
      if (!f.constant && materials[m].textured)
        return invalidInput(
            "emissive[material {}]: scenario \"{}\" scales the material's emission texture while another sets a "
            "constant radiance; a blend of the two is not one override (give both scenarios the same kind)",
            mi, t.scenario->name);
      sum += t.weight * (f.constant ? f.value : f.value * materials[m].radiance);
    }
    if (Status s = out.setEmissive({mi, EmissiveOverride::Mode::kRadiance, sum}); !s) return s;
  }

  bool any_sh = false;
  for (const Term& t : terms) any_sh |= t.scenario->lights.sky().sh.has_value();
  Sky sky;
  if (any_sh) {
    std::array<glm::vec3, 9> sh{};
    for (const Term& t : terms) {
      const auto c = t.scenario->lights.sky().radianceSh();
      for (int i = 0; i < 9; ++i) sh[i] += t.weight * c[i];
    }
    sky.sh = sh;
  } else {
    for (const Term& t : terms) sky.radiance += t.weight * t.scenario->lights.sky().radiance;
  }
  if (Status s = out.setSky(sky); !s) return s;
  return out;
}

}  // namespace lightlink::lights
