#include "core/lights/light_set.h"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <numbers>
#include <set>
#include <sstream>

namespace lightlink::lights {
namespace {
// In double: a float's square overflows beyond ~1.8e19 (a direction of 1e25 would have an
// infinite length and normalise to zero) and underflows below ~1e-19.
double directionLength(glm::vec3 d) { return glm::length(glm::dvec3(d)); }
}  // namespace

namespace {

using json = nlohmann::json;
constexpr float kPi = std::numbers::pi_v<float>;

std::string kindName(Light::Kind k) { return std::string(enumName(kLightKindNames, k)); }

Status checkScalar(float v, std::string_view path) {
  if (!std::isfinite(v)) return invalidInput("{}: {} is not finite", path, v);
  if (v < 0.0f) return invalidInput("{}: {} is negative", path, v);
  if (v > kMaxLightValue) return invalidInput("{}: {} exceeds the limit {:g}", path, v, kMaxLightValue);
  return {};
}

Status checkColor(glm::vec3 c, std::string_view path) {
  for (int i = 0; i < 3; ++i)
    if (Status s = checkScalar(c[i], fmt::format("{}[{}]", path, i)); !s) return s;
  return {};
}

Status checkFinite(glm::vec3 v, std::string_view path) {
  for (int i = 0; i < 3; ++i)
    if (!std::isfinite(v[i])) return invalidInput("{}[{}]: {} is not finite", path, i, v[i]);
  return {};
}

// ---- JSON readers: each names the field path on error ---------------------------------

Expected<float> readNumber(const json& j, const std::string& path) {
  if (!j.is_number()) return invalidInput("{}: expected a number, got {}", path, j.type_name());
  const double d = j.get<double>();
  if (!std::isfinite(d)) return invalidInput("{}: {} is not finite", path, d);
  if (std::abs(d) > 3.0e38) return invalidInput("{}: {} is out of float range", path, d);
  return static_cast<float>(d);
}

Expected<glm::vec3> readVec3(const json& j, const std::string& path) {
  if (!j.is_array() || j.size() != 3) return invalidInput("{}: expected an array of 3 numbers", path);
  glm::vec3 v(0.0f);
  for (int i = 0; i < 3; ++i) {
    auto x = readNumber(j[i], fmt::format("{}[{}]", path, i));
    if (!x) return x.status();
    v[i] = *x;
  }
  return v;
}

Expected<bool> readBool(const json& j, const std::string& path) {
  if (!j.is_boolean()) return invalidInput("{}: expected true or false, got {}", path, j.type_name());
  return j.get<bool>();
}

Status checkKeys(const json& obj, const std::string& path, std::initializer_list<const char*> allowed) {
  for (auto it = obj.begin(); it != obj.end(); ++it) {
    if (std::none_of(allowed.begin(), allowed.end(), [&](const char* k) { return it.key() == k; }))
      return invalidInput("{}.{}: unknown field", path, it.key());
  }
  return {};
}

// Reads one "lights" entry; `path` names it ("lights[2]").
Expected<LightPatch> readLightPatch(const json& j, const std::string& path) {
  if (!j.is_object()) return invalidInput("{}: expected an object", path);
  if (Status s = checkKeys(j, path,
                           {"id", "type", "color", "intensity", "range", "position", "direction",
                            "inner_cone_angle", "outer_cone_angle", "baked", "remove", "name"});
      !s)
    return s;
  LightPatch p;
  if (!j.contains("id") || !j["id"].is_string()) return invalidInput("{}.id: expected a string", path);
  p.id = j["id"].get<std::string>();
  if (j.contains("remove")) {
    auto r = readBool(j["remove"], path + ".remove");
    if (!r) return r.status();
    p.remove = *r;
  }
  if (j.contains("type")) {
    const json& t = j["type"];
    if (!t.is_string()) return invalidInput("{}.type: expected a string", path);
    const std::string ts = t.get<std::string>();
    p.kind = enumValue(kLightKindNames, ts);
    if (!p.kind) return invalidInput("{}.type: \"{}\" is not point, spot or directional", path, ts);
  }
  if (j.contains("name")) {
    if (!j["name"].is_string()) return invalidInput("{}.name: expected a string", path);
    p.name = j["name"].get<std::string>();
  }
  auto vec = [&](const char* key, std::optional<glm::vec3>& out) -> Status {
    if (!j.contains(key)) return {};
    auto v = readVec3(j[key], path + "." + key);
    if (!v) return v.status();
    out = *v;
    return {};
  };
  auto num = [&](const char* key, std::optional<float>& out) -> Status {
    if (!j.contains(key)) return {};
    auto v = readNumber(j[key], path + "." + key);
    if (!v) return v.status();
    out = *v;
    return {};
  };
  for (Status s : {vec("color", p.color), num("intensity", p.intensity), num("range", p.range),
                   vec("position", p.position), vec("direction", p.direction),
                   num("inner_cone_angle", p.inner_cone_angle), num("outer_cone_angle", p.outer_cone_angle)})
    if (!s) return s;
  if (j.contains("baked")) {
    auto b = readBool(j["baked"], path + ".baked");
    if (!b) return b.status();
    p.baked = *b;
  }
  if (Status s = p.validateFields(path); !s) return s;
  return p;
}

Expected<Sky> readSky(const json& j, const std::string& path) {
  if (!j.is_object()) return invalidInput("{}: expected an object", path);
  if (Status s = checkKeys(j, path, {"radiance", "sh"}); !s) return s;
  Sky sky;
  if (j.contains("radiance")) {
    auto v = readVec3(j["radiance"], path + ".radiance");
    if (!v) return v.status();
    sky.radiance = *v;
  }
  if (j.contains("sh")) {
    const json& sh = j["sh"];
    if (!sh.is_array() || sh.size() != 9)
      return invalidInput("{}.sh: expected 9 RGB coefficients (3 bands, docs/sh.md order)", path);
    std::array<glm::vec3, 9> c;
    for (int i = 0; i < 9; ++i) {
      auto v = readVec3(sh[i], fmt::format("{}.sh[{}]", path, i));
      if (!v) return v.status();
      c[i] = *v;
    }
    sky.sh = c;
  }
  if (Status s = LightSet::validate(sky, path); !s) return s;
  return sky;
}

Expected<EmissiveOverride> readEmissive(const json& j, const std::string& path) {
  if (!j.is_object()) return invalidInput("{}: expected an object", path);
  if (Status s = checkKeys(j, path, {"material", "scale", "radiance"}); !s) return s;
  EmissiveOverride e;
  if (!j.contains("material") || !j["material"].is_number_integer())
    return invalidInput("{}.material: expected a material index (integer)", path);
  const auto m = j["material"].get<long long>();
  if (m < 0 || m > 1'000'000'000) return invalidInput("{}.material: {} is not a material index", path, m);
  e.material = static_cast<int>(m);
  if (j.contains("scale") == j.contains("radiance"))
    return invalidInput("{}: give exactly one of \"scale\" and \"radiance\"", path);
  const char* key = j.contains("scale") ? "scale" : "radiance";
  e.mode = j.contains("scale") ? EmissiveOverride::Mode::kScale : EmissiveOverride::Mode::kRadiance;
  if (j[key].is_number()) {
    auto v = readNumber(j[key], path + "." + key);
    if (!v) return v.status();
    e.value = glm::vec3(*v);
  } else {
    auto v = readVec3(j[key], path + "." + key);
    if (!v) return v.status();
    e.value = *v;
  }
  if (Status s = LightSet::validate(e, path); !s) return s;
  return e;
}

nlohmann::ordered_json vec3Json(glm::vec3 v) { return nlohmann::ordered_json::array({v.x, v.y, v.z}); }

}  // namespace

bool Sky::emits() const {
  if (sh) return std::any_of(sh->begin(), sh->end(), [](glm::vec3 c) { return c != glm::vec3(0.0f); });
  return radiance != glm::vec3(0.0f);
}

std::array<glm::vec3, 9> Sky::radianceSh() const {
  if (sh) return *sh;
  std::array<glm::vec3, 9> c{};
  c[0] = radiance * (2.0f * std::sqrt(kPi));  // L_00 of a constant: L * sqrt(4 pi)
  return c;
}

bool sameLight(const Light& a, const Light& b) {
  return a.kind == b.kind && a.color == b.color && a.intensity == b.intensity && a.range == b.range &&
         a.inner_cone_angle == b.inner_cone_angle && a.outer_cone_angle == b.outer_cone_angle &&
         a.position == b.position && a.direction == b.direction;
}

LightSet LightSet::fromSceneLights(const std::vector<Light>& scene_lights) {
  LightSet set;
  std::set<std::string> names;
  std::set<std::string> duplicated;
  for (const auto& l : scene_lights)
    if (!names.insert(l.name).second) duplicated.insert(l.name);
  for (std::size_t i = 0; i < scene_lights.size(); ++i) {
    const auto& l = scene_lights[i];
    LightEntry e{l.name.empty() || duplicated.count(l.name) ? fmt::format("light{}", i) : l.name, l, true};
    // Scene lights were validated by ingest; a collision of a name with a generated id is
    // resolved by suffixing, so fromSceneLights never fails.
    while (set.find(e.id)) e.id += "_";
    set.lights_.push_back(std::move(e));
  }
  set.version_ = 1;
  return set;
}

Status LightSet::validate(const LightEntry& e, std::string_view path) {
  if (e.id.empty()) return invalidInput("{}.id: must not be empty", path);
  if (e.id.size() > 256) return invalidInput("{}.id: longer than 256 characters", path);
  const auto& l = e.light;
  if (Status s = checkColor(l.color, fmt::format("{}.color", path)); !s) return s;
  if (Status s = checkScalar(l.intensity, fmt::format("{}.intensity", path)); !s) return s;
  if (Status s = checkScalar(l.range, fmt::format("{}.range", path)); !s) return s;
  if (Status s = checkFinite(l.position, fmt::format("{}.position", path)); !s) return s;
  if (Status s = checkFinite(l.direction, fmt::format("{}.direction", path)); !s) return s;
  if (l.kind != Light::Kind::kPoint && !(directionLength(l.direction) > 1e-6))
    return invalidInput("{}.direction: must be a non-zero vector", path);
  if (l.kind == Light::Kind::kSpot) {
    if (!std::isfinite(l.outer_cone_angle) || l.outer_cone_angle <= 0.0f || l.outer_cone_angle > 0.5f * kPi + 1e-6f)
      return invalidInput("{}.outer_cone_angle: {} is outside (0, pi/2]", path, l.outer_cone_angle);
    if (!std::isfinite(l.inner_cone_angle) || l.inner_cone_angle < 0.0f || l.inner_cone_angle >= l.outer_cone_angle)
      return invalidInput("{}.inner_cone_angle: {} is outside [0, outer_cone_angle = {})", path,
                          l.inner_cone_angle, l.outer_cone_angle);
  }
  return {};
}

Status LightSet::validate(const EmissiveOverride& e, std::string_view path) {
  if (e.material < 0) return invalidInput("{}.material: {} is not a material index", path, e.material);
  return checkColor(e.value, fmt::format("{}.{}", path, e.mode == EmissiveOverride::Mode::kScale ? "scale" : "radiance"));
}

Status LightSet::checkMaterials(std::size_t material_count) const {
  for (std::size_t i = 0; i < emissive_.size(); ++i)
    if (emissive_[i].material < 0 || static_cast<std::size_t>(emissive_[i].material) >= material_count)
      return invalidInput("emissive[{}].material: {} is not a material of the scene ({} materials)", i,
                          emissive_[i].material, material_count);
  return {};
}

Status LightSet::validate(const Sky& sky, std::string_view path) {
  if (Status s = checkColor(sky.radiance, fmt::format("{}.radiance", path)); !s) return s;
  if (sky.sh) {
    // SH coefficients may be negative (only the function must be >= 0), so only finiteness
    // and magnitude are checked.
    for (int i = 0; i < 9; ++i)
      for (int c = 0; c < 3; ++c) {
        const float v = (*sky.sh)[i][c];
        if (!std::isfinite(v)) return invalidInput("{}.sh[{}][{}]: {} is not finite", path, i, c, v);
        if (std::abs(v) > kMaxLightValue)
          return invalidInput("{}.sh[{}][{}]: {} exceeds the limit {:g}", path, i, c, v, kMaxLightValue);
      }
  }
  return {};
}

namespace {
// The direction stored is unit length, whatever length the caller gave.
void normalizeDirection(LightEntry& e) {
  const double len = directionLength(e.light.direction);
  if (len > 0.0) e.light.direction = glm::vec3(glm::dvec3(e.light.direction) / len);
}
}  // namespace

void LightPatch::applyTo(LightEntry& e) const {
  if (kind) e.light.kind = *kind;
  if (name) e.light.name = *name;
  if (color) e.light.color = *color;
  if (intensity) e.light.intensity = *intensity;
  if (range) e.light.range = *range;
  if (position) e.light.position = *position;
  if (direction) e.light.direction = *direction;
  if (inner_cone_angle) e.light.inner_cone_angle = *inner_cone_angle;
  if (outer_cone_angle) e.light.outer_cone_angle = *outer_cone_angle;
  if (baked) e.baked = *baked;
}

Status LightPatch::validateFields(std::string_view path) const {
  if (id.empty()) return invalidInput("{}.id: must not be empty", path);
  if (id.size() > 256) return invalidInput("{}.id: longer than 256 characters", path);
  if (color)
    if (Status s = checkColor(*color, fmt::format("{}.color", path)); !s) return s;
  if (intensity)
    if (Status s = checkScalar(*intensity, fmt::format("{}.intensity", path)); !s) return s;
  if (range)
    if (Status s = checkScalar(*range, fmt::format("{}.range", path)); !s) return s;
  if (position)
    if (Status s = checkFinite(*position, fmt::format("{}.position", path)); !s) return s;
  if (direction) {
    if (Status s = checkFinite(*direction, fmt::format("{}.direction", path)); !s) return s;
    // Zero is no direction for any kind: a later "type" change would make it one.
    if (!(directionLength(*direction) > 1e-6)) return invalidInput("{}.direction: must be a non-zero vector", path);
  }
  for (auto [key, angle] : {std::pair{"inner_cone_angle", inner_cone_angle}, std::pair{"outer_cone_angle", outer_cone_angle}})
    if (angle && !(*angle >= 0.0f && *angle <= 0.5f * kPi + 1e-6f))
      return invalidInput("{}.{}: {} is outside [0, pi/2]", path, key, *angle);
  if (inner_cone_angle && outer_cone_angle && !(*inner_cone_angle < *outer_cone_angle))
    return invalidInput("{}.inner_cone_angle: {} is not below outer_cone_angle = {}", path, *inner_cone_angle,
                        *outer_cone_angle);
  return {};
}

const LightEntry* LightSet::find(std::string_view id) const {
  for (const auto& e : lights_)
    if (e.id == id) return &e;
  return nullptr;
}

bool LightSet::anyBaked() const {
  return std::any_of(lights_.begin(), lights_.end(), [](const LightEntry& e) { return e.baked; });
}

Status LightSet::add(LightEntry entry) {
  if (Status s = validate(entry, fmt::format("lights[\"{}\"]", entry.id)); !s) return s;
  if (find(entry.id)) return invalidInput("lights[\"{}\"].id: duplicate id", entry.id);
  normalizeDirection(entry);
  lights_.push_back(std::move(entry));
  ++version_;
  return {};
}

Status LightSet::modify(const LightEntry& entry) {
  auto it = std::find_if(lights_.begin(), lights_.end(), [&](const LightEntry& e) { return e.id == entry.id; });
  if (it == lights_.end()) return invalidInput("lights[\"{}\"].id: unknown id", entry.id);
  if (Status s = validate(entry, fmt::format("lights[\"{}\"]", entry.id)); !s) return s;
  *it = entry;
  normalizeDirection(*it);
  ++version_;
  return {};
}

Status LightSet::remove(std::string_view id) {
  auto it = std::find_if(lights_.begin(), lights_.end(), [&](const LightEntry& e) { return e.id == id; });
  if (it == lights_.end()) return invalidInput("lights[\"{}\"].id: unknown id", id);
  lights_.erase(it);
  ++version_;
  return {};
}

Status LightSet::setEmissive(const EmissiveOverride& e) {
  if (Status s = validate(e, fmt::format("emissive[material {}]", e.material)); !s) return s;
  auto it = std::lower_bound(emissive_.begin(), emissive_.end(), e.material,
                             [](const EmissiveOverride& a, int m) { return a.material < m; });
  if (it != emissive_.end() && it->material == e.material) *it = e;
  else emissive_.insert(it, e);
  ++version_;
  return {};
}

Status LightSet::clearEmissive(int material) {
  auto it = std::find_if(emissive_.begin(), emissive_.end(), [&](const auto& e) { return e.material == material; });
  if (it == emissive_.end()) return invalidInput("emissive[material {}]: no override to clear", material);
  emissive_.erase(it);
  ++version_;
  return {};
}

Status LightSet::setSky(const Sky& sky) {
  if (Status s = validate(sky, "sky"); !s) return s;
  sky_ = sky;
  ++version_;
  return {};
}

Status LightSet::setEmissiveBaked(bool baked) {
  emissive_baked_ = baked;
  ++version_;
  return {};
}

Expected<LightSetPatch> LightSetPatch::fromJson(const json& j) {
  if (!j.is_object()) return invalidInput("light set: expected a JSON object");
  if (Status s = checkKeys(j, "light set", {"version", "lights", "sky", "emissive", "emissive_baked"}); !s) return s;
  if (!j.contains("version")) return invalidInput("version: missing (this build reads version {})", kLightSetSchemaVersion);
  if (!j["version"].is_number_integer() || j["version"].get<long long>() != kLightSetSchemaVersion)
    return invalidInput("version: {} is not supported (this build reads version {})", j["version"].dump(),
                        kLightSetSchemaVersion);
  LightSetPatch patch;
  if (j.contains("lights")) {
    const json& arr = j["lights"];
    if (!arr.is_array()) return invalidInput("lights: expected an array");
    std::set<std::string> seen;
    for (std::size_t i = 0; i < arr.size(); ++i) {
      const std::string path = fmt::format("lights[{}]", i);
      auto p = readLightPatch(arr[i], path);
      if (!p) return p.status();
      if (!seen.insert(p->id).second) return invalidInput("{}.id: duplicate id \"{}\"", path, p->id);
      patch.lights.push_back(std::move(*p));
    }
  }
  if (j.contains("sky")) {
    auto sky = readSky(j["sky"], "sky");
    if (!sky) return sky.status();
    patch.sky = *sky;
  }
  if (j.contains("emissive")) {
    const json& arr = j["emissive"];
    if (!arr.is_array()) return invalidInput("emissive: expected an array");
    for (std::size_t i = 0; i < arr.size(); ++i) {
      auto e = readEmissive(arr[i], fmt::format("emissive[{}]", i));
      if (!e) return e.status();
      patch.emissive.push_back(*e);
    }
  }
  if (j.contains("emissive_baked")) {
    auto b = readBool(j["emissive_baked"], "emissive_baked");
    if (!b) return b.status();
    patch.emissive_baked = *b;
  }
  return patch;
}

Status LightSet::apply(const LightSetPatch& patch) {
  LightSet next = *this;  // all or nothing
  for (std::size_t i = 0; i < patch.lights.size(); ++i) {
    const LightPatch& p = patch.lights[i];
    const std::string path = fmt::format("lights[{}]", i);
    auto it = std::find_if(next.lights_.begin(), next.lights_.end(), [&](const auto& e) { return e.id == p.id; });
    if (p.remove) {
      if (it == next.lights_.end()) return invalidInput("{}.id: unknown id \"{}\" cannot be removed", path, p.id);
      next.lights_.erase(it);
      continue;
    }
    if (it == next.lights_.end() && !p.kind) return invalidInput("{}.type: missing for new light \"{}\"", path, p.id);
    LightEntry e = it != next.lights_.end() ? *it : LightEntry{p.id, {}, true};
    p.applyTo(e);
    if (Status s = validate(e, path); !s) return s;
    normalizeDirection(e);
    if (it != next.lights_.end()) *it = std::move(e);
    else next.lights_.push_back(std::move(e));
  }
  if (patch.sky) next.sky_ = *patch.sky;
  for (const EmissiveOverride& e : patch.emissive) {
    auto it = std::lower_bound(next.emissive_.begin(), next.emissive_.end(), e.material,
                               [](const EmissiveOverride& a, int m) { return a.material < m; });
    if (it != next.emissive_.end() && it->material == e.material) *it = e;
    else next.emissive_.insert(it, e);
  }
  if (patch.emissive_baked) next.emissive_baked_ = *patch.emissive_baked;
  next.version_ = version_ + 1;
  *this = std::move(next);
  return {};
}

Status LightSet::apply(const json& j) {
  auto patch = LightSetPatch::fromJson(j);
  if (!patch) return patch.status();
  return apply(*patch);
}

Expected<LightSet> LightSet::fromJson(const json& j) {
  LightSet set;
  if (Status s = set.apply(j); !s) return s;
  return set;
}

namespace {
// Parses light-set JSON text. JSON has no Inf, so a number such as 1e999 that overflows double
// is a parse error (nlohmann: "number overflow"), raised before any schema check could name
// the field; the callback tracks the path the parser has reached (object keys, array indices)
// so that error names the field like every other light-set error does (DESIGN.md sec 6:
// non-finite input is rejected naming the field; tests/stability).
Expected<json> parseText(const std::string& text, std::string_view origin) {
  struct Level {
    bool array = false;
    std::size_t count = 0;  // array: completed elements
    std::string key;        // object: the last key read
  };
  std::vector<Level> levels;
  auto track = [&levels](int /*depth*/, json::parse_event_t event, json& parsed) {
    switch (event) {
      case json::parse_event_t::object_start: levels.push_back({false, 0, {}}); break;
      case json::parse_event_t::array_start: levels.push_back({true, 0, {}}); break;
      case json::parse_event_t::key: levels.back().key = parsed.get<std::string>(); break;
      case json::parse_event_t::object_end:
      case json::parse_event_t::array_end:
        levels.pop_back();
        if (!levels.empty() && levels.back().array) ++levels.back().count;
        break;
      case json::parse_event_t::value:
        if (!levels.empty() && levels.back().array) ++levels.back().count;
        break;
    }
    return true;
  };
  try {
    return json::parse(text, track);
  } catch (const json::exception& e) {
    std::string at;
    for (const Level& l : levels) {
      if (l.array) at += fmt::format("[{}]", l.count);
      else if (!l.key.empty()) at += (at.empty() ? "" : ".") + l.key;
    }
    if (at.empty()) return invalidInput("{}: not valid JSON: {}", origin, e.what());
    return invalidInput("{}: not valid JSON at {}: {}", origin, at, e.what());
  }
}

Expected<std::string> readFile(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return notFound("{}: cannot open light set", path);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

Status prefixed(const Status& s, std::string_view origin) { return Status(s.code(), fmt::format("{}: {}", origin, s.message())); }
}  // namespace

Expected<LightSetPatch> LightSetPatch::parse(const std::string& text, std::string_view origin) {
  auto j = parseText(text, origin);
  if (!j) return j.status();
  auto patch = fromJson(*j);
  if (!patch) return prefixed(patch.status(), origin);
  return patch;
}

Expected<LightSetPatch> LightSetPatch::load(const std::string& path) {
  auto text = readFile(path);
  if (!text) return text.status();
  return parse(*text, path);
}

Expected<LightSet> LightSet::load(const std::string& path) {
  LightSet set;
  if (Status s = set.applyFile(path); !s) return s;
  return set;
}

Status LightSet::applyFile(const std::string& path) {
  auto patch = LightSetPatch::load(path);
  if (!patch) return patch.status();
  if (Status s = apply(*patch); !s) return prefixed(s, path);
  return {};
}

nlohmann::ordered_json LightSet::toJson() const {
  nlohmann::ordered_json j;
  j["version"] = kLightSetSchemaVersion;
  j["lights"] = nlohmann::ordered_json::array();
  for (const auto& e : lights_) {
    nlohmann::ordered_json l;
    l["id"] = e.id;
    l["type"] = kindName(e.light.kind);
    if (!e.light.name.empty()) l["name"] = e.light.name;
    l["color"] = vec3Json(e.light.color);
    l["intensity"] = e.light.intensity;
    if (e.light.range > 0.0f) l["range"] = e.light.range;
    if (e.light.kind != Light::Kind::kDirectional) l["position"] = vec3Json(e.light.position);
    if (e.light.kind != Light::Kind::kPoint) l["direction"] = vec3Json(e.light.direction);
    if (e.light.kind == Light::Kind::kSpot) {
      l["inner_cone_angle"] = e.light.inner_cone_angle;
      l["outer_cone_angle"] = e.light.outer_cone_angle;
    }
    l["baked"] = e.baked;
    j["lights"].push_back(l);
  }
  nlohmann::ordered_json sky;
  sky["radiance"] = vec3Json(sky_.radiance);
  if (sky_.sh) {
    sky["sh"] = nlohmann::ordered_json::array();
    for (const auto& c : *sky_.sh) sky["sh"].push_back(vec3Json(c));
  }
  j["sky"] = sky;
  j["emissive"] = nlohmann::ordered_json::array();
  for (const auto& e : emissive_) {
    nlohmann::ordered_json o;
    o["material"] = e.material;
    o[e.mode == EmissiveOverride::Mode::kScale ? "scale" : "radiance"] = vec3Json(e.value);
    j["emissive"].push_back(o);
  }
  j["emissive_baked"] = emissive_baked_;
  return j;
}

Status LightSet::save(const std::string& path) const {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  if (!out) return ioError("{}: cannot write light set", path);
  out << toJson().dump(2) << "\n";
  if (!out) return ioError("{}: write failed", path);
  return {};
}

}  // namespace lightlink::lights
