// LightUpdate: typed calls and light-set JSON -> lightlink.v1.UpdateLightsRequest.
#include "clients/client/light_update.h"

#include <cmath>
#include <fstream>
#include <numbers>
#include <sstream>

#include "proto/lightlink.pb.h"

namespace lightlink::client {
namespace {

// The same ceiling as the daemon and core's LightSet (kMaxLightValue): beyond it a value is
// a unit mistake, not a light.
constexpr double kMaxValue = 1e12;
constexpr std::size_t kMaxIdLength = 256;

std::string num(double v) { return fmt::format("{}", v); }

Status checkFinite(double v, const std::string& path) {
  if (!std::isfinite(v)) return invalidInput("{}: {} is not a finite number", path, num(v));
  return {};
}

Status checkNonNegative(double v, const std::string& path, double max = kMaxValue) {
  if (Status s = checkFinite(v, path); !s) return s;
  if (v < 0.0) return invalidInput("{}: {} is negative", path, num(v));
  if (v > max) return invalidInput("{}: {} is above the limit {}", path, num(v), num(max));
  return {};
}

Status checkVec(const Vec3& v, const std::string& path, bool non_negative) {
  const float c[3] = {v.x, v.y, v.z};
  for (int i = 0; i < 3; ++i) {
    const std::string p = fmt::format("{}[{}]", path, i);
    if (Status s = non_negative ? checkNonNegative(c[i], p) : checkFinite(c[i], p); !s) return s;
  }
  return {};
}

Status validateLight(const LightFields& l, const std::string& path, bool require_type) {
  if (l.id.empty()) return invalidInput("{}.id: must not be empty", path);
  if (l.id.size() > kMaxIdLength)
    return invalidInput("{}.id: {} characters, at most {}", path, l.id.size(), kMaxIdLength);
  if (require_type && !l.type) return invalidInput("{}.type: required for a new light '{}'", path, l.id);
  if (l.color)
    if (Status s = checkVec(*l.color, path + ".color", true); !s) return s;
  if (l.intensity)
    if (Status s = checkNonNegative(*l.intensity, path + ".intensity"); !s) return s;
  if (l.range)
    if (Status s = checkNonNegative(*l.range, path + ".range"); !s) return s;
  if (l.position)
    if (Status s = checkVec(*l.position, path + ".position", false); !s) return s;
  if (l.direction) {
    if (Status s = checkVec(*l.direction, path + ".direction", false); !s) return s;
    const Vec3& d = *l.direction;
    if (d.x == 0.0f && d.y == 0.0f && d.z == 0.0f) return invalidInput("{}.direction: must not be zero", path);
  }
  constexpr double kHalfPi = std::numbers::pi / 2.0;
  if (l.inner_cone_angle)
    if (Status s = checkNonNegative(*l.inner_cone_angle, path + ".inner_cone_angle", kHalfPi); !s) return s;
  if (l.outer_cone_angle)
    if (Status s = checkNonNegative(*l.outer_cone_angle, path + ".outer_cone_angle", kHalfPi); !s) return s;
  if (l.inner_cone_angle && l.outer_cone_angle && !(*l.inner_cone_angle < *l.outer_cone_angle))
    return invalidInput("{}.inner_cone_angle: {} must be below outer_cone_angle {}", path, num(*l.inner_cone_angle),
                        num(*l.outer_cone_angle));
  return {};
}

v1::LightType toProto(LightType t) {
  switch (t) {
    case LightType::kPoint: return v1::LIGHT_TYPE_POINT;
    case LightType::kSpot: return v1::LIGHT_TYPE_SPOT;
    case LightType::kDirectional: return v1::LIGHT_TYPE_DIRECTIONAL;
  }
  return v1::LIGHT_TYPE_UNSPECIFIED;
}

void setVec(v1::Vec3* out, const Vec3& v) {
  out->set_x(v.x);
  out->set_y(v.y);
  out->set_z(v.z);
}

void fill(v1::Light* out, const LightFields& l) {
  out->set_id(l.id);
  if (l.type) out->set_type(toProto(*l.type));
  if (l.color) setVec(out->mutable_color(), *l.color);
  if (l.intensity) out->set_intensity(*l.intensity);
  if (l.range) out->set_range(*l.range);
  if (l.position) setVec(out->mutable_position(), *l.position);
  if (l.direction) setVec(out->mutable_direction(), *l.direction);
  if (l.inner_cone_angle) out->set_inner_cone_angle(*l.inner_cone_angle);
  if (l.outer_cone_angle) out->set_outer_cone_angle(*l.outer_cone_angle);
  if (l.baked) out->set_baked(*l.baked);
  if (l.name) out->set_name(*l.name);
}

template <typename List>
bool containsId(const List& list, const std::string& id) {
  for (const auto& l : list)
    if (l.id() == id) return true;
  return false;
}

Status checkMaterial(int material, const std::string& path) {
  if (material < 0) return invalidInput("{}.material: {} is negative", path, material);
  return {};
}

// ---- light-set JSON reading: every accessor names the document path it reads.

Expected<double> readNumber(const nlohmann::json& j, const std::string& path) {
  if (!j.is_number()) return invalidInput("{}: {} is not a number", path, j.dump());
  const double v = j.get<double>();
  if (!std::isfinite(v) || std::abs(v) > 3.0e38) return invalidInput("{}: {} is not a finite number", path, j.dump());
  return v;
}

Expected<Vec3> readVec3(const nlohmann::json& j, const std::string& path) {
  if (!j.is_array() || j.size() != 3) return invalidInput("{}: expected an array of 3 numbers, got {}", path, j.dump());
  float c[3];
  for (int i = 0; i < 3; ++i) {
    auto v = readNumber(j[std::size_t(i)], fmt::format("{}[{}]", path, i));
    if (!v) return v.status();
    c[i] = float(*v);
  }
  return Vec3{c[0], c[1], c[2]};
}

// A number (grey) or 3 numbers.
Expected<Vec3> readRgb(const nlohmann::json& j, const std::string& path) {
  if (j.is_number()) {
    auto v = readNumber(j, path);
    if (!v) return v.status();
    return Vec3{float(*v), float(*v), float(*v)};
  }
  return readVec3(j, path);
}

Expected<std::string> readString(const nlohmann::json& j, const std::string& path) {
  if (!j.is_string()) return invalidInput("{}: {} is not a string", path, j.dump());
  return j.get<std::string>();
}

Expected<bool> readBool(const nlohmann::json& j, const std::string& path) {
  if (!j.is_boolean()) return invalidInput("{}: {} is not true or false", path, j.dump());
  return j.get<bool>();
}

Status checkKeys(const nlohmann::json& obj, const std::string& path, std::initializer_list<const char*> allowed) {
  if (!obj.is_object()) return invalidInput("{}: expected an object, got {}", path, obj.dump());
  for (auto it = obj.begin(); it != obj.end(); ++it) {
    bool ok = false;
    for (const char* a : allowed) ok |= it.key() == a;
    if (!ok) return invalidInput("{}{}{}: unknown field", path, path.empty() ? "" : ".", it.key());
  }
  return {};
}

struct JsonLight {
  LightFields fields;
  bool remove = false;
};

Expected<JsonLight> readLight(const nlohmann::json& j, const std::string& path) {
  if (Status s = checkKeys(j, path,
                           {"id", "type", "name", "color", "intensity", "range", "position", "direction",
                            "inner_cone_angle", "outer_cone_angle", "baked", "remove"});
      !s)
    return s;
  JsonLight out;
  LightFields& l = out.fields;
  if (!j.contains("id")) return invalidInput("{}.id: required", path);
  auto id = readString(j["id"], path + ".id");
  if (!id) return id.status();
  l.id = *id;
  if (j.contains("remove")) {
    auto r = readBool(j["remove"], path + ".remove");
    if (!r) return r.status();
    out.remove = *r;
  }
  if (j.contains("type")) {
    auto t = readString(j["type"], path + ".type");
    if (!t) return t.status();
    auto type = parseLightType(*t);
    if (!type) return invalidInput("{}.type: {}", path, type.status().message());
    l.type = *type;
  }
  if (j.contains("name")) {
    auto n = readString(j["name"], path + ".name");
    if (!n) return n.status();
    l.name = *n;
  }
  if (j.contains("baked")) {
    auto b = readBool(j["baked"], path + ".baked");
    if (!b) return b.status();
    l.baked = *b;
  }
  for (auto [key, dst] : {std::pair{"color", &l.color}, std::pair{"position", &l.position},
                          std::pair{"direction", &l.direction}}) {
    if (!j.contains(key)) continue;
    auto v = readVec3(j[key], path + "." + key);
    if (!v) return v.status();
    *dst = *v;
  }
  for (auto [key, dst] : {std::pair{"intensity", &l.intensity}, std::pair{"range", &l.range},
                          std::pair{"inner_cone_angle", &l.inner_cone_angle},
                          std::pair{"outer_cone_angle", &l.outer_cone_angle}}) {
    if (!j.contains(key)) continue;
    auto v = readNumber(j[key], path + "." + key);
    if (!v) return v.status();
    *dst = float(*v);
  }
  return out;
}

}  // namespace

Expected<LightType> parseLightType(const std::string& text) {
  if (text == "point") return LightType::kPoint;
  if (text == "spot") return LightType::kSpot;
  if (text == "directional") return LightType::kDirectional;
  return invalidInput("'{}' is not a light type (point, spot, directional)", text);
}

LightUpdate::LightUpdate() : request_(std::make_unique<v1::UpdateLightsRequest>()) {}
LightUpdate::LightUpdate(const LightUpdate& o) : request_(std::make_unique<v1::UpdateLightsRequest>(*o.request_)) {}
LightUpdate& LightUpdate::operator=(const LightUpdate& o) {
  if (this != &o) *request_ = *o.request_;
  return *this;
}
LightUpdate::LightUpdate(LightUpdate&&) noexcept = default;
LightUpdate& LightUpdate::operator=(LightUpdate&&) noexcept = default;
LightUpdate::~LightUpdate() = default;

Status LightUpdate::add(const LightFields& light) {
  const std::string path = fmt::format("add[{}]", request_->add_size());
  if (Status s = validateLight(light, path, true); !s) return s;
  if (containsId(request_->add(), light.id)) return invalidInput("{}.id: duplicate id '{}'", path, light.id);
  fill(request_->add_add(), light);
  return {};
}

Status LightUpdate::modify(const LightFields& light) {
  const std::string path = fmt::format("modify[{}]", request_->modify_size());
  if (Status s = validateLight(light, path, false); !s) return s;
  if (containsId(request_->modify(), light.id)) return invalidInput("{}.id: duplicate id '{}'", path, light.id);
  fill(request_->add_modify(), light);
  return {};
}

Status LightUpdate::remove(const std::string& id) {
  const std::string path = fmt::format("remove[{}]", request_->remove_size());
  if (id.empty()) return invalidInput("{}: must not be empty", path);
  if (id.size() > kMaxIdLength) return invalidInput("{}: {} characters, at most {}", path, id.size(), kMaxIdLength);
  for (const auto& r : request_->remove())
    if (r == id) return invalidInput("{}: duplicate id '{}'", path, id);
  request_->add_remove(id);
  return {};
}

Status LightUpdate::replaceLights(const std::vector<LightFields>& lights) {
  v1::UpdateLightsRequest trial = *request_;
  trial.clear_add();
  for (std::size_t i = 0; i < lights.size(); ++i) {
    const std::string path = fmt::format("add[{}]", i);
    if (Status s = validateLight(lights[i], path, true); !s) return s;
    if (containsId(trial.add(), lights[i].id)) return invalidInput("{}.id: duplicate id '{}'", path, lights[i].id);
    fill(trial.add_add(), lights[i]);
  }
  trial.set_replace_lights(true);
  *request_ = std::move(trial);
  return {};
}

Status LightUpdate::emissiveScale(int material, Vec3 scale) {
  const std::string path = fmt::format("emissive[{}]", request_->emissive_size());
  if (Status s = checkMaterial(material, path); !s) return s;
  if (Status s = checkVec(scale, path + ".scale", true); !s) return s;
  auto* e = request_->add_emissive();
  e->set_material(material);
  setVec(e->mutable_scale(), scale);
  return {};
}

Status LightUpdate::emissiveRadiance(int material, Vec3 radiance) {
  const std::string path = fmt::format("emissive[{}]", request_->emissive_size());
  if (Status s = checkMaterial(material, path); !s) return s;
  if (Status s = checkVec(radiance, path + ".radiance", true); !s) return s;
  auto* e = request_->add_emissive();
  e->set_material(material);
  setVec(e->mutable_radiance(), radiance);
  return {};
}

Status LightUpdate::clearEmissive(int material) {
  const std::string path = fmt::format("emissive[{}]", request_->emissive_size());
  if (Status s = checkMaterial(material, path); !s) return s;
  auto* e = request_->add_emissive();
  e->set_material(material);
  e->set_clear(true);
  return {};
}

Status LightUpdate::sky(Vec3 radiance, const std::vector<Vec3>& sh) {
  if (Status s = checkVec(radiance, "sky.radiance", true); !s) return s;
  if (!sh.empty() && sh.size() != 9) return invalidInput("sky.sh: {} coefficients, expected 0 or 9", sh.size());
  for (std::size_t i = 0; i < sh.size(); ++i)
    if (Status s = checkVec(sh[i], fmt::format("sky.sh[{}]", i), false); !s) return s;
  auto* sky = request_->mutable_sky();
  sky->Clear();
  setVec(sky->mutable_radiance(), radiance);
  for (const Vec3& c : sh) setVec(sky->add_sh(), c);
  return {};
}

void LightUpdate::emissiveBaked(bool baked) { request_->set_emissive_baked(baked); }

bool LightUpdate::empty() const {
  const auto& r = *request_;
  return !r.replace_lights() && r.remove_size() == 0 && r.modify_size() == 0 && r.add_size() == 0 &&
         r.emissive_size() == 0 && !r.has_sky() && !r.has_emissive_baked();
}

void LightUpdate::applyToIds(std::set<std::string>& ids) const {
  const auto& r = *request_;
  if (r.replace_lights()) ids.clear();
  for (const auto& id : r.remove()) ids.erase(id);
  for (const auto& l : r.add()) ids.insert(l.id());
}

Expected<LightUpdate> LightUpdate::fromLightSetJson(const nlohmann::json& doc, const std::set<std::string>* known_ids) {
  if (Status s = checkKeys(doc, "", {"version", "lights", "sky", "emissive", "emissive_baked"}); !s) return s;
  if (!doc.contains("version")) return invalidInput("version: required (this build reads version 1)");
  if (!doc["version"].is_number_integer() || doc["version"].get<long long>() != 1)
    return invalidInput("version: {} is not supported (this build reads version 1)", doc["version"].dump());
  LightUpdate u;
  auto& r = *u.request_;
  if (doc.contains("lights")) {
    const auto& lights = doc["lights"];
    if (!lights.is_array()) return invalidInput("lights: expected an array, got {}", lights.dump());
    std::set<std::string> seen;
    for (std::size_t i = 0; i < lights.size(); ++i) {
      const std::string path = fmt::format("lights[{}]", i);
      auto l = readLight(lights[i], path);
      if (!l) return l.status();
      const std::string& id = l->fields.id;
      if (!seen.insert(id).second) return invalidInput("{}.id: duplicate id \"{}\"", path, id);
      if (l->remove) {
        if (known_ids && !known_ids->contains(id))
          return invalidInput("{}.id: cannot remove \"{}\": the scene has no such light", path, id);
        if (Status s = validateLight(l->fields, path, false); !s) return s;
        r.add_remove(id);
        continue;
      }
      const bool is_new = known_ids ? !known_ids->contains(id) : l->fields.type.has_value();
      if (Status s = validateLight(l->fields, path, is_new); !s) return s;
      fill(is_new ? r.add_add() : r.add_modify(), l->fields);
    }
  }
  if (doc.contains("sky")) {
    const auto& sky = doc["sky"];
    if (Status s = checkKeys(sky, "sky", {"radiance", "sh"}); !s) return s;
    Vec3 radiance;
    if (sky.contains("radiance")) {
      auto v = readVec3(sky["radiance"], "sky.radiance");
      if (!v) return v.status();
      radiance = *v;
    }
    std::vector<Vec3> sh;
    if (sky.contains("sh")) {
      if (!sky["sh"].is_array() || sky["sh"].size() != 9)
        return invalidInput("sky.sh: expected 9 RGB triples, got {}", sky["sh"].dump());
      for (std::size_t i = 0; i < 9; ++i) {
        auto v = readVec3(sky["sh"][i], fmt::format("sky.sh[{}]", i));
        if (!v) return v.status();
        sh.push_back(*v);
      }
    }
    if (Status s = u.sky(radiance, sh); !s) return s;
  }
  if (doc.contains("emissive")) {
    const auto& em = doc["emissive"];
    if (!em.is_array()) return invalidInput("emissive: expected an array, got {}", em.dump());
    for (std::size_t i = 0; i < em.size(); ++i) {
      const std::string path = fmt::format("emissive[{}]", i);
      if (Status s = checkKeys(em[i], path, {"material", "scale", "radiance"}); !s) return s;
      if (!em[i].contains("material") || !em[i]["material"].is_number_integer())
        return invalidInput("{}.material: required, an integer index into the glTF's materials", path);
      const long long m = em[i]["material"].get<long long>();
      if (m < 0 || m > std::numeric_limits<int>::max()) return invalidInput("{}.material: {} is out of range", path, m);
      const bool has_scale = em[i].contains("scale"), has_radiance = em[i].contains("radiance");
      if (has_scale == has_radiance) return invalidInput("{}: exactly one of scale and radiance", path);
      const char* key = has_scale ? "scale" : "radiance";
      auto v = readRgb(em[i][key], path + "." + key);
      if (!v) return v.status();
      if (Status s = checkVec(*v, path + "." + key, true); !s) return s;
      auto* e = r.add_emissive();
      e->set_material(int(m));
      setVec(has_scale ? e->mutable_scale() : e->mutable_radiance(), *v);
    }
  }
  if (doc.contains("emissive_baked")) {
    auto b = readBool(doc["emissive_baked"], "emissive_baked");
    if (!b) return b.status();
    r.set_emissive_baked(*b);
  }
  return u;
}

Expected<LightUpdate> LightUpdate::fromLightSetText(const std::string& text, const std::set<std::string>* known_ids) {
  nlohmann::json doc = nlohmann::json::parse(text, nullptr, /*allow_exceptions=*/false);
  if (doc.is_discarded()) return invalidInput("light set: not valid JSON");
  return fromLightSetJson(doc, known_ids);
}

Expected<LightUpdate> LightUpdate::fromLightSetFile(const std::string& path, const std::set<std::string>* known_ids) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return notFound("{}: cannot open light set", path);
  std::ostringstream ss;
  ss << in.rdbuf();
  auto u = fromLightSetText(ss.str(), known_ids);
  if (!u) return Status(u.status().code(), path + ": " + u.status().message());
  return u;
}

}  // namespace lightlink::client
