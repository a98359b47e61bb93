// LightSet: the lighting a relight is asked to compute, separate from the static scene.
//
// The precomputation fixes geometry and materials; everything a designer changes while the
// daemon runs lives here: punctual lights with stable string ids (KHR_lights_punctual
// fields plus a `baked` flag), per-material emission overrides and a sky. A light marked
// baked also has its direct irradiance written into lightmap texels; a realtime light
// (baked = false) contributes only through indirect light, because the engine renders its
// direct part (DESIGN.md sec 4 "Direct light"). Emissive surfaces are one more kind of light
// with one set-wide flag, `emissiveBaked()`: baked (the default), their direct light is
// sampled into lightmap texels with soft shadows; not baked, the engine draws it.
//
// Every successful change bumps `version()` (monotonic uint64, never reused by one
// LightSet), so the service and the relight can name the state they computed. Values are
// validated where they enter: NaN/Inf, negative or absurd (> 1e12) intensities and colours,
// unknown or duplicate ids are rejected as invalidInput naming the field path
// (`lights[2].intensity: -1 is negative`). Units are those of docs/units.md: candela for
// point/spot, lux for directional, radiance for emission and sky. The JSON form is
// documented in docs/lightset.md (schema version 1).
#pragma once

#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <glm/glm.hpp>
#include <nlohmann/json.hpp>

#include "core/common/status.h"
#include "core/scene/scene.h"

namespace lightlink::relight {

// Largest intensity, colour, emission or sky value accepted: beyond it a value is a unit
// mistake (or an overflow waiting to happen in fp16 caches), not a light.
inline constexpr float kMaxLightValue = 1e12f;
inline constexpr int kLightSetSchemaVersion = 1;

struct LightEntry {
  std::string id;       // stable, unique in the set
  scene::Light light;   // units of docs/units.md; direction unit length after validation
  bool baked = true;    // direct light also written into lightmap texels
};

// Replaces a material's emission for relighting. kScale multiplies the scene's emission
// (per RGB channel); kRadiance replaces it by a uniform radiance (texture ignored).
struct EmissiveOverride {
  enum class Mode { kScale, kRadiance };
  int material = -1;            // index into Scene::materials
  Mode mode = Mode::kScale;
  glm::vec3 value{1.0f};        // factor (kScale) or radiance (kRadiance)
};

// Sky radiance arriving from directions where a cache sees no geometry. Uniform `radiance`
// plus, optionally, 3-band SH radiance coefficients (docs/sh.md convention, per channel)
// that replace the uniform value when present.
struct Sky {
  glm::vec3 radiance{0.0f};
  std::optional<std::array<glm::vec3, 9>> sh;

  bool emits() const;
  // The radiance SH (9 coefficients per channel) this sky stands for.
  std::array<glm::vec3, 9> radianceSh() const;
};

class LightSet {
 public:
  LightSet() = default;

  // The scene's glTF lights, all baked. Ids are the light names when they are non-empty and
  // unique, else "light<i>" (i = index in Scene::lights).
  static LightSet fromScene(const scene::Scene& scene);
  // A set from JSON text / a file (docs/lightset.md). Parse and schema errors name the
  // field path.
  static Expected<LightSet> fromJson(const nlohmann::json& json);
  static Expected<LightSet> load(const std::string& path);

  // Merges a light-set JSON into this set: lights whose id exists are overridden field by
  // field (only the fields given), new ids are added, `"remove": true` removes; "sky" and
  // "emissive" entries replace the ones here. All or nothing: on error the set is unchanged.
  Status apply(const nlohmann::json& json);
  Status applyFile(const std::string& path);

  nlohmann::ordered_json toJson() const;
  Status save(const std::string& path) const;

  Status add(LightEntry entry);
  Status modify(const LightEntry& entry);  // replaces the light with entry.id
  Status remove(std::string_view id);
  Status setEmissive(const EmissiveOverride& override_);
  Status clearEmissive(int material);
  Status setSky(const Sky& sky);
  // Baked (default): the direct light of emissive surfaces is written into lightmap texels.
  // Not baked: it is left to the engine, only its bounced light is in the lightmap.
  Status setEmissiveBaked(bool baked);

  std::uint64_t version() const { return version_; }
  const std::vector<LightEntry>& lights() const { return lights_; }
  const std::vector<EmissiveOverride>& emissive() const { return emissive_; }
  const Sky& sky() const { return sky_; }
  bool emissiveBaked() const { return emissive_baked_; }
  const LightEntry* find(std::string_view id) const;
  bool anyBaked() const;

  // Checks one light; `path` names it in messages ("lights[2]").
  static Status validate(const LightEntry& entry, std::string_view path);
  static Status validate(const EmissiveOverride& e, std::string_view path);
  static Status validate(const Sky& sky, std::string_view path);
  // Every emissive override names a material of a scene with `material_count` materials (a
  // light-set file knows no scene: checked where the set meets one).
  Status checkMaterials(std::size_t material_count) const;

 private:
  std::vector<LightEntry> lights_;
  std::vector<EmissiveOverride> emissive_;  // sorted by material, one per material
  Sky sky_;
  bool emissive_baked_ = true;
  std::uint64_t version_ = 0;
};

// Field-by-field equality of the parts of a light that change what it emits.
bool sameLight(const scene::Light& a, const scene::Light& b);

}  // namespace lightlink::relight
