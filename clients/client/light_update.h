// LightUpdate: one UpdateLights request built from typed calls or from a light-set JSON
// (docs/lightset.md), so editors and scripts never fill protobuf messages by hand.
//
// The request is applied by the daemon all or nothing, in the order of the proto: replace
// (`replaceLights`), then `remove`, `modify`, `add`, emissive overrides, sky, emissive_baked.
// Values are checked here as they enter, by core/lights' rules (lights::LightPatch::
// validateFields for every entry, lights::LightSet::validate for a whole new light), with
// messages naming the field path, so a script learns of its mistake before a round trip; the
// daemon checks again, because it cannot trust any client.
//
// Light-set JSON -> request. The document is read by lights::LightSetPatch, the same reader
// the CLI and the daemon use, so the three accept the same documents. A light-set file merges into the scene's lights: an entry whose
// id the scene has overrides the fields given, a new id is added (its `type` required),
// `"remove": true` removes. Which ids the scene has is the caller's knowledge (SceneHandle
// keeps the ids OpenScene returned and the changes made through it); when it is not known
// (`known_ids == nullptr`) an entry that names a `type` is an add and one that does not is a
// modify.
#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "clients/client/textures.h"
#include "core/common/status.h"
#include "core/lights/light_set.h"

namespace lightlink::v1 {
class UpdateLightsRequest;
}

namespace lightlink::client {

enum class LightType { kPoint, kSpot, kDirectional };

// Fields of a punctual light (docs/units.md). Unset optionals: for add, the documented
// defaults; for modify, unchanged.
struct LightFields {
  std::string id;
  std::optional<LightType> type;
  std::optional<Vec3> color;              // linear RGB >= 0
  std::optional<float> intensity;         // cd (point, spot) or lux (directional)
  std::optional<float> range;             // metres, 0 = infinite
  std::optional<Vec3> position;           // metres
  std::optional<Vec3> direction;          // non-zero
  std::optional<float> inner_cone_angle;  // radians
  std::optional<float> outer_cone_angle;
  std::optional<bool> baked;
  std::optional<std::string> name;
};

class LightUpdate {
 public:
  LightUpdate();
  LightUpdate(const LightUpdate&);
  LightUpdate& operator=(const LightUpdate&);
  LightUpdate(LightUpdate&&) noexcept;
  LightUpdate& operator=(LightUpdate&&) noexcept;
  ~LightUpdate();

  // Each returns the first problem with its argument, naming the field
  // (`add[0].intensity: nan is not finite`); on error the update is unchanged.
  Status add(const LightFields& light);
  Status modify(const LightFields& light);
  Status remove(const std::string& id);
  // The scene's punctual lights become exactly `lights`.
  Status replaceLights(const std::vector<LightFields>& lights);
  Status emissiveScale(int material, Vec3 scale);
  Status emissiveRadiance(int material, Vec3 radiance);
  Status clearEmissive(int material);
  // Uniform sky radiance, or 9 RGB SH coefficients (docs/sh.md) when `sh` is non-empty.
  Status sky(Vec3 radiance, const std::vector<Vec3>& sh = {});
  Status sky(const lights::Sky& sky);
  void emissiveBaked(bool baked);

  bool empty() const;
  // Ids this update adds and removes (replaceLights: the new set), to keep a handle's
  // knowledge of the scene's light ids current after the daemon accepts it.
  void applyToIds(std::set<std::string>& ids) const;

  const v1::UpdateLightsRequest& proto() const { return *request_; }
  v1::UpdateLightsRequest& proto() { return *request_; }

  // A light-set JSON document (docs/lightset.md, schema version 1) as one update; errors
  // name the field path of the document (`lights[2].position[1]: expected a number, got string`).
  static Expected<LightUpdate> fromLightSetPatch(const lights::LightSetPatch& patch,
                                                 const std::set<std::string>* known_ids);
  static Expected<LightUpdate> fromLightSetJson(const nlohmann::json& doc, const std::set<std::string>* known_ids);
  static Expected<LightUpdate> fromLightSetText(const std::string& text, const std::set<std::string>* known_ids);
  static Expected<LightUpdate> fromLightSetFile(const std::string& path, const std::set<std::string>* known_ids);

 private:
  std::unique_ptr<v1::UpdateLightsRequest> request_;
};

// Parses "point" | "spot" | "directional" (lights::kLightKindNames).
Expected<LightType> parseLightType(const std::string& text);

}  // namespace lightlink::client
