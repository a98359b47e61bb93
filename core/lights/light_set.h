// LightSet: the lighting a relight is asked to compute, separate from the static scene; and
// LightSetPatch, the one reader of the light-set JSON (docs/lightset.md, schema version 1).
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
// point/spot, lux for directional, radiance for emission and sky.
//
// One schema, one validator: the CLI and the daemon read light-set files through LightSet,
// the client library (clients/client/light_update.h) through LightSetPatch, which knows no
// current set and so turns the document into changes. This library depends on lightlink_common,
// glm and nlohmann_json only (no Embree, OpenMesh, TBB or scene loaders), so it is exported
// with the client library (docs/clients.md "Using the client library from CMake").
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
#include "core/lights/light.h"

namespace lightlink::lights {

// Largest intensity, colour, emission or sky value accepted: beyond it a value is a unit
// mistake (or an overflow waiting to happen in fp16 caches), not a light.
inline constexpr float kMaxLightValue = 1e12f;
inline constexpr int kLightSetSchemaVersion = 1;

struct LightEntry {
  std::string id;       // stable, unique in the set
  Light light;   // units of docs/units.md; direction unit length after validation
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

// One entry of a light-set document's "lights": the fields it gives (unset = the default
// for a new light, unchanged for an existing one), or `remove`.
struct LightPatch {
  std::string id;
  bool remove = false;
  std::optional<Light::Kind> kind;
  std::optional<std::string> name;
  std::optional<glm::vec3> color;
  std::optional<float> intensity;
  std::optional<float> range;
  std::optional<glm::vec3> position;
  std::optional<glm::vec3> direction;  // any length but zero; stored normalised
  std::optional<float> inner_cone_angle;
  std::optional<float> outer_cone_angle;
  std::optional<bool> baked;

  // Writes the fields given over `entry` (defaults for a new light, or the light modified).
  void applyTo(LightEntry& entry) const;
  // The checks one field allows without knowing the rest of the light: id, finite, >= 0 and
  // <= kMaxLightValue where it applies, a non-zero direction, cone angles in [0, pi/2] with
  // inner < outer when both are given. The whole light is checked by LightSet::validate
  // once merged. `path` names the entry ("lights[2]").
  Status validateFields(std::string_view path) const;
};

// A light-set document as changes: what LightSet::apply merges, and what the client library
// turns into an UpdateLights request without knowing the scene's lights. Parsing checks the
// schema (version, known fields, value types, duplicate ids) and every value a field can
// check on its own; whether an entry adds a light (and so needs a "type") depends on the set
// it meets, so LightSet::apply and the client decide that.
struct LightSetPatch {
  std::vector<LightPatch> lights;        // document order; lights[i] is the path in messages
  std::optional<Sky> sky;                // replaces the sky
  std::vector<EmissiveOverride> emissive;  // document order; a later one for a material wins
  std::optional<bool> emissive_baked;

  static Expected<LightSetPatch> fromJson(const nlohmann::json& json);
  // JSON text; `origin` (a file path, or "light set") prefixes messages, and a JSON syntax
  // error names the field the parser had reached (`lights[1].intensity`).
  static Expected<LightSetPatch> parse(const std::string& text, std::string_view origin = "light set");
  static Expected<LightSetPatch> load(const std::string& path);
};

class LightSet {
 public:
  LightSet() = default;

  // A scene's glTF lights (Scene::lights), all baked. Ids are the light names when they are
  // non-empty and unique, else "light<i>" (i = index in `scene_lights`).
  static LightSet fromSceneLights(const std::vector<Light>& scene_lights);
  // A set from JSON text / a file (docs/lightset.md). Parse and schema errors name the
  // field path.
  static Expected<LightSet> fromJson(const nlohmann::json& json);
  static Expected<LightSet> load(const std::string& path);

  // Merges a light-set JSON into this set: lights whose id exists are overridden field by
  // field (only the fields given), new ids are added, `"remove": true` removes; "sky" and
  // "emissive" entries replace the ones here. All or nothing: on error the set is unchanged.
  Status apply(const nlohmann::json& json);
  Status apply(const LightSetPatch& patch);
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
bool sameLight(const Light& a, const Light& b);

}  // namespace lightlink::lights
