// LightUpdate: typed calls and light-set JSON -> lightlink.v1.UpdateLightsRequest. The schema
// and every value rule are core/lights' (LightSetPatch, LightSet::validate); this file only
// maps them onto the request.
#include "clients/client/light_update.h"

#include "core/common/enum_names.h"
#include "proto/lightlink.pb.h"

namespace lightlink::client {
namespace {

using lights::LightPatch;
using lights::LightSetPatch;

constexpr std::size_t kMaxIdLength = 256;  // as lights::LightPatch::validateFields

glm::vec3 toGlm(const Vec3& v) { return {v.x, v.y, v.z}; }

// The typed fields as the light-set library's patch, so typed calls and JSON documents are
// checked by the same rules (lights::LightPatch::validateFields, LightSet::validate).
LightPatch toPatch(const LightFields& l) {
  LightPatch p;
  p.id = l.id;
  if (l.type) p.kind = static_cast<lights::Light::Kind>(*l.type);
  p.name = l.name;
  if (l.color) p.color = toGlm(*l.color);
  p.intensity = l.intensity;
  p.range = l.range;
  if (l.position) p.position = toGlm(*l.position);
  if (l.direction) p.direction = toGlm(*l.direction);
  p.inner_cone_angle = l.inner_cone_angle;
  p.outer_cone_angle = l.outer_cone_angle;
  p.baked = l.baked;
  return p;
}
static_assert(static_cast<int>(LightType::kPoint) == static_cast<int>(lights::Light::Kind::kPoint) &&
              static_cast<int>(LightType::kSpot) == static_cast<int>(lights::Light::Kind::kSpot) &&
              static_cast<int>(LightType::kDirectional) == static_cast<int>(lights::Light::Kind::kDirectional));

// A new light: its fields, then the whole light over the defaults the daemon fills in
// (lights::Light), as LightSet::apply checks one.
Status validateNew(const LightPatch& p, const std::string& path) {
  if (Status s = p.validateFields(path); !s) return s;
  if (!p.kind) return invalidInput("{}.type: missing for new light \"{}\"", path, p.id);
  lights::LightEntry entry{p.id, {}, true};
  p.applyTo(entry);
  return lights::LightSet::validate(entry, path);
}

v1::LightType toProto(lights::Light::Kind k) {
  switch (k) {
    case lights::Light::Kind::kPoint: return v1::LIGHT_TYPE_POINT;
    case lights::Light::Kind::kSpot: return v1::LIGHT_TYPE_SPOT;
    case lights::Light::Kind::kDirectional: return v1::LIGHT_TYPE_DIRECTIONAL;
  }
  return v1::LIGHT_TYPE_UNSPECIFIED;
}

void setVec(v1::Vec3* out, const glm::vec3& v) {
  out->set_x(v.x);
  out->set_y(v.y);
  out->set_z(v.z);
}

void fill(v1::Light* out, const LightPatch& l) {
  out->set_id(l.id);
  if (l.kind) out->set_type(toProto(*l.kind));
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

void fill(v1::EmissiveOverride* out, const lights::EmissiveOverride& e) {
  out->set_material(e.material);
  setVec(e.mode == lights::EmissiveOverride::Mode::kScale ? out->mutable_scale() : out->mutable_radiance(), e.value);
}

template <typename List>
bool containsId(const List& list, const std::string& id) {
  for (const auto& l : list)
    if (l.id() == id) return true;
  return false;
}

Status checkEmissive(const lights::EmissiveOverride& e, const std::string& path) {
  return lights::LightSet::validate(e, path);
}

}  // namespace

Expected<LightType> parseLightType(const std::string& text) {
  if (auto kind = enumValue(lights::kLightKindNames, text)) return static_cast<LightType>(*kind);
  return invalidInput("\"{}\" is not point, spot or directional", text);
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
  const LightPatch p = toPatch(light);
  if (Status s = validateNew(p, path); !s) return s;
  if (containsId(request_->add(), light.id)) return invalidInput("{}.id: duplicate id \"{}\"", path, light.id);
  fill(request_->add_add(), p);
  return {};
}

Status LightUpdate::modify(const LightFields& light) {
  const std::string path = fmt::format("modify[{}]", request_->modify_size());
  const LightPatch p = toPatch(light);
  if (Status s = p.validateFields(path); !s) return s;
  if (containsId(request_->modify(), light.id)) return invalidInput("{}.id: duplicate id \"{}\"", path, light.id);
  fill(request_->add_modify(), p);
  return {};
}

Status LightUpdate::remove(const std::string& id) {
  const std::string path = fmt::format("remove[{}]", request_->remove_size());
  if (id.empty()) return invalidInput("{}: must not be empty", path);
  if (id.size() > kMaxIdLength) return invalidInput("{}: longer than {} characters", path, kMaxIdLength);
  for (const auto& r : request_->remove())
    if (r == id) return invalidInput("{}: duplicate id \"{}\"", path, id);
  request_->add_remove(id);
  return {};
}

Status LightUpdate::replaceLights(const std::vector<LightFields>& lights) {
  v1::UpdateLightsRequest trial = *request_;
  trial.clear_add();
  for (std::size_t i = 0; i < lights.size(); ++i) {
    const std::string path = fmt::format("add[{}]", i);
    const LightPatch p = toPatch(lights[i]);
    if (Status s = validateNew(p, path); !s) return s;
    if (containsId(trial.add(), lights[i].id)) return invalidInput("{}.id: duplicate id \"{}\"", path, lights[i].id);
    fill(trial.add_add(), p);
  }
  trial.set_replace_lights(true);
  *request_ = std::move(trial);
  return {};
}

Status LightUpdate::emissiveScale(int material, Vec3 scale) {
  const lights::EmissiveOverride e{material, lights::EmissiveOverride::Mode::kScale, toGlm(scale)};
  if (Status s = checkEmissive(e, fmt::format("emissive[{}]", request_->emissive_size())); !s) return s;
  fill(request_->add_emissive(), e);
  return {};
}

Status LightUpdate::emissiveRadiance(int material, Vec3 radiance) {
  const lights::EmissiveOverride e{material, lights::EmissiveOverride::Mode::kRadiance, toGlm(radiance)};
  if (Status s = checkEmissive(e, fmt::format("emissive[{}]", request_->emissive_size())); !s) return s;
  fill(request_->add_emissive(), e);
  return {};
}

Status LightUpdate::clearEmissive(int material) {
  const std::string path = fmt::format("emissive[{}]", request_->emissive_size());
  if (material < 0) return invalidInput("{}.material: {} is not a material index", path, material);
  auto* e = request_->add_emissive();
  e->set_material(material);
  e->set_clear(true);
  return {};
}

Status LightUpdate::sky(Vec3 radiance, const std::vector<Vec3>& sh) {
  if (!sh.empty() && sh.size() != 9) return invalidInput("sky.sh: {} coefficients, expected 0 or 9", sh.size());
  lights::Sky sky{toGlm(radiance), std::nullopt};
  if (!sh.empty()) {
    sky.sh.emplace();
    for (std::size_t i = 0; i < 9; ++i) (*sky.sh)[i] = toGlm(sh[i]);
  }
  return this->sky(sky);
}

Status LightUpdate::sky(const lights::Sky& sky) {
  if (Status s = lights::LightSet::validate(sky, "sky"); !s) return s;
  auto* out = request_->mutable_sky();
  out->Clear();
  setVec(out->mutable_radiance(), sky.radiance);
  if (sky.sh)
    for (const glm::vec3& c : *sky.sh) setVec(out->add_sh(), c);
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

Expected<LightUpdate> LightUpdate::fromLightSetPatch(const LightSetPatch& patch, const std::set<std::string>* known_ids) {
  LightUpdate u;
  auto& r = *u.request_;
  for (std::size_t i = 0; i < patch.lights.size(); ++i) {
    const LightPatch& l = patch.lights[i];
    const std::string path = fmt::format("lights[{}]", i);
    if (l.remove) {
      if (known_ids && !known_ids->contains(l.id))
        return invalidInput("{}.id: unknown id \"{}\" cannot be removed", path, l.id);
      r.add_remove(l.id);
      continue;
    }
    // Without the scene's ids, a typed entry adds and an untyped one modifies.
    const bool is_new = known_ids ? !known_ids->contains(l.id) : l.kind.has_value();
    if (is_new) {
      if (Status s = validateNew(l, path); !s) return s;
    }
    fill(is_new ? r.add_add() : r.add_modify(), l);
  }
  if (patch.sky)
    if (Status s = u.sky(*patch.sky); !s) return s;
  for (const lights::EmissiveOverride& e : patch.emissive) fill(r.add_emissive(), e);
  if (patch.emissive_baked) r.set_emissive_baked(*patch.emissive_baked);
  return u;
}

Expected<LightUpdate> LightUpdate::fromLightSetJson(const nlohmann::json& doc, const std::set<std::string>* known_ids) {
  auto patch = LightSetPatch::fromJson(doc);
  if (!patch) return patch.status();
  return fromLightSetPatch(*patch, known_ids);
}

Expected<LightUpdate> LightUpdate::fromLightSetText(const std::string& text, const std::set<std::string>* known_ids) {
  auto patch = LightSetPatch::parse(text);
  if (!patch) return patch.status();
  return fromLightSetPatch(*patch, known_ids);
}

Expected<LightUpdate> LightUpdate::fromLightSetFile(const std::string& path, const std::set<std::string>* known_ids) {
  auto patch = LightSetPatch::load(path);
  if (!patch) return patch.status();
  auto u = fromLightSetPatch(*patch, known_ids);
  if (!u) return Status(u.status().code(), path + ": " + u.status().message());
  return u;
}

}  // namespace lightlink::client
