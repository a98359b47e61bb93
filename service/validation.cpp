#include "service/validation.h"

#include <map>

#include <fmt/format.h>

namespace lightlink::service {
namespace {

glm::vec3 toVec(const v1::Vec3& v) { return {v.x(), v.y(), v.z()}; }

Expected<scene::Light::Kind> kindFrom(v1::LightType type, const std::string& path) {
  switch (type) {
    case v1::LIGHT_TYPE_POINT: return scene::Light::Kind::kPoint;
    case v1::LIGHT_TYPE_SPOT: return scene::Light::Kind::kSpot;
    case v1::LIGHT_TYPE_DIRECTIONAL: return scene::Light::Kind::kDirectional;
    default: return invalidInput("{}.type: must be LIGHT_TYPE_POINT, _SPOT or _DIRECTIONAL", path);
  }
}

// Writes the fields present in `l` over `entry` (add/set: over defaults; modify: over the
// existing light) with core's light-set rules: each field as LightPatch::validateFields
// checks it (the rules of a light-set file and of the client library), then the whole light.
Status mergeLight(const v1::Light& l, const std::string& path, relight::LightEntry& entry) {
  lights::LightPatch patch;
  patch.id = l.id();
  if (l.type() != v1::LIGHT_TYPE_UNSPECIFIED) {
    auto kind = kindFrom(l.type(), path);
    if (!kind) return kind.status();
    patch.kind = *kind;
  }
  if (l.has_name()) {
    if (l.name().size() > kMaxNameBytes) return invalidInput("{}.name: longer than {} bytes", path, kMaxNameBytes);
    patch.name = l.name();
  }
  if (l.has_color()) patch.color = toVec(l.color());
  if (l.has_intensity()) patch.intensity = l.intensity();
  if (l.has_range()) patch.range = l.range();
  if (l.has_position()) patch.position = toVec(l.position());
  if (l.has_direction()) patch.direction = toVec(l.direction());
  if (l.has_inner_cone_angle()) patch.inner_cone_angle = l.inner_cone_angle();
  if (l.has_outer_cone_angle()) patch.outer_cone_angle = l.outer_cone_angle();
  if (l.has_baked()) patch.baked = l.baked();
  if (Status s = patch.validateFields(path); !s) return s;
  patch.applyTo(entry);
  return relight::LightSet::validate(entry, path);
}

Status checkId(const std::string& id, const std::string& path) {
  if (id.empty()) return invalidInput("{}.id: must not be empty", path);
  if (id.size() > 256) return invalidInput("{}.id: longer than 256 characters", path);
  return {};
}

}  // namespace

Expected<bake::BakeOptions> bakeOptionsFrom(const v1::OpenSceneRequest& r, const relight::RelightOptions& relight_defaults) {
  if (r.name().size() > kMaxNameBytes) return invalidInput("name: longer than {} bytes", kMaxNameBytes);
  if (r.path().size() > kMaxPathBytes) return invalidInput("path: longer than {} bytes", kMaxPathBytes);
  bake::BakeOptionsBuilder builder("medium", relight_defaults, "options.");
  // The deprecated typed fields first, each under its own name in messages (0/empty = unset).
  const auto legacy = [&](bool given, std::string_view option, const std::string& value, std::string_view field) {
    return given ? builder.set(option, value, field) : Status{};
  };
  if (Status s = legacy(!r.preset().empty(), "preset", r.preset(), "preset"); !s) return s;
  if (Status s = legacy(r.surfels() != 0, "surfels", std::to_string(r.surfels()), "surfels"); !s) return s;
  if (Status s = legacy(r.links() != 0, "links", std::to_string(r.links()), "links"); !s) return s;
  if (Status s = legacy(r.bands() != 0, "bands", std::to_string(r.bands()), "bands"); !s) return s;
  if (Status s = legacy(r.rays() != 0, "rays", std::to_string(r.rays()), "rays"); !s) return s;
  if (Status s = legacy(r.grid_spacing() != 0.0f, "grid-spacing", fmt::format("{}", r.grid_spacing()), "grid_spacing");
      !s)
    return s;
  if (Status s = legacy(r.texel_size() != 0.0f, "texel-size", fmt::format("{}", r.texel_size()), "texel_size"); !s)
    return s;
  if (Status s = legacy(!r.hierarchy().empty(), "hierarchy", r.hierarchy(), "hierarchy"); !s) return s;
  // Then the map, in key order so that the first error reported does not depend on hashing.
  const std::map<std::string, std::string> options(r.options().begin(), r.options().end());
  for (const auto& [name, value] : options)
    if (Status s = builder.set(name, value); !s) return s;
  return builder.build();
}

Expected<precompute::PrecomputeOptions> precomputeOptionsFrom(const v1::OpenSceneRequest& r) {
  auto o = bakeOptionsFrom(r);
  if (!o) return o.status();
  return o->precompute;
}

Status applyUpdate(const v1::UpdateLightsRequest& r, std::size_t material_count, relight::LightSet& lights) {
  if (static_cast<std::size_t>(r.add_size()) > kMaxChangesPerRequest ||
      static_cast<std::size_t>(r.modify_size()) > kMaxChangesPerRequest ||
      static_cast<std::size_t>(r.remove_size()) > kMaxChangesPerRequest ||
      static_cast<std::size_t>(r.emissive_size()) > kMaxChangesPerRequest)
    return invalidInput("add/modify/remove/emissive: more than {} entries in one request", kMaxChangesPerRequest);
  if (r.wait_ms() > kMaxWaitMs) return invalidInput("wait_ms: {} is above the limit of {}", r.wait_ms(), kMaxWaitMs);

  if (r.replace_lights()) {
    std::vector<std::string> ids;
    for (const auto& e : lights.lights()) ids.push_back(e.id);
    for (const auto& id : ids)
      if (Status s = lights.remove(id); !s) return s;
  }
  for (int i = 0; i < r.remove_size(); ++i) {
    const std::string path = fmt::format("remove[{}]", i);
    if (lights.find(r.remove(i)) == nullptr)
      return notFound("{}: no light '{}' in the scene", path, r.remove(i).substr(0, 256));
    if (Status s = lights.remove(r.remove(i)); !s) return s;
  }
  for (int i = 0; i < r.modify_size(); ++i) {
    const std::string path = fmt::format("modify[{}]", i);
    const v1::Light& l = r.modify(i);
    if (Status s = checkId(l.id(), path); !s) return s;
    const relight::LightEntry* existing = lights.find(l.id());
    if (existing == nullptr) return notFound("{}.id: no light '{}' in the scene", path, l.id());
    relight::LightEntry entry = *existing;
    if (Status s = mergeLight(l, path, entry); !s) return s;
    if (Status s = lights.modify(entry); !s) return s;
  }
  for (int i = 0; i < r.add_size(); ++i) {
    const std::string path = fmt::format("add[{}]", i);
    const v1::Light& l = r.add(i);
    if (Status s = checkId(l.id(), path); !s) return s;
    if (l.type() == v1::LIGHT_TYPE_UNSPECIFIED) return invalidInput("{}.type: required for a new light", path);
    if (lights.find(l.id()) != nullptr) return invalidInput("{}.id: a light '{}' already exists", path, l.id());
    if (lights.lights().size() >= kMaxLightsPerScene)
      return invalidInput("{}: the scene already has {} lights (the limit)", path, kMaxLightsPerScene);
    relight::LightEntry entry;
    entry.id = l.id();
    if (Status s = mergeLight(l, path, entry); !s) return s;
    if (Status s = lights.add(std::move(entry)); !s) return s;
  }
  for (int i = 0; i < r.emissive_size(); ++i) {
    const std::string path = fmt::format("emissive[{}]", i);
    const v1::EmissiveOverride& e = r.emissive(i);
    if (e.material() < 0 || static_cast<std::size_t>(e.material()) >= material_count)
      return invalidInput("{}.material: {} is not a material of the scene (0..{})", path, e.material(),
                          static_cast<long long>(material_count) - 1);
    if (e.clear()) {
      if (Status s = lights.clearEmissive(e.material()); !s) return s;
      continue;
    }
    relight::EmissiveOverride o;
    o.material = e.material();
    if (e.has_scale()) {
      o.mode = relight::EmissiveOverride::Mode::kScale;
      o.value = toVec(e.scale());
    } else if (e.has_radiance()) {
      o.mode = relight::EmissiveOverride::Mode::kRadiance;
      o.value = toVec(e.radiance());
    } else {
      return invalidInput("{}: set scale or radiance, or clear", path);
    }
    if (Status s = relight::LightSet::validate(o, path); !s) return s;
    if (Status s = lights.setEmissive(o); !s) return s;
  }
  if (r.has_sky()) {
    // Every value, finiteness included, is checked by core's light-set rules below.
    relight::Sky sky;
    if (r.sky().has_radiance()) {
      sky.radiance = toVec(r.sky().radiance());
    }
    if (r.sky().sh_size() != 0) {
      if (r.sky().sh_size() != 9)
        return invalidInput("sky.sh: {} coefficients given, expected 0 or 9", r.sky().sh_size());
      std::array<glm::vec3, 9> sh{};
      for (int i = 0; i < 9; ++i) sh[i] = toVec(r.sky().sh(i));
      sky.sh = sh;
    }
    if (Status s = relight::LightSet::validate(sky, "sky"); !s) return s;
    if (Status s = lights.setSky(sky); !s) return s;
  }
  if (r.has_emissive_baked()) {
    if (Status s = lights.setEmissiveBaked(r.emissive_baked()); !s) return s;
  }
  return {};
}

Status validateSpec(const v1::ResultSpec& spec, int result_bands, std::string_view field) {
  if (spec.bands() < 0 || spec.bands() > result_bands)
    return invalidInput("{}.bands: {} is out of range (0 = all, 1..{})", field, spec.bands(), result_bands);
  if (!v1::Component_IsValid(spec.component()))
    return invalidInput("{}.component: {} is not a Component", field, static_cast<int>(spec.component()));
  if (!v1::Precision_IsValid(spec.precision()))
    return invalidInput("{}.precision: {} is not a Precision", field, static_cast<int>(spec.precision()));
  return {};
}

v1::Light toProtoLight(const relight::LightEntry& entry) {
  const auto vec = [](glm::vec3 v, v1::Vec3* out) {
    out->set_x(v.x);
    out->set_y(v.y);
    out->set_z(v.z);
  };
  const auto& l = entry.light;
  v1::Light out;
  out.set_id(entry.id);
  switch (l.kind) {
    case scene::Light::Kind::kPoint: out.set_type(v1::LIGHT_TYPE_POINT); break;
    case scene::Light::Kind::kSpot: out.set_type(v1::LIGHT_TYPE_SPOT); break;
    case scene::Light::Kind::kDirectional: out.set_type(v1::LIGHT_TYPE_DIRECTIONAL); break;
  }
  vec(l.color, out.mutable_color());
  out.set_intensity(l.intensity);
  out.set_range(l.range);
  vec(l.position, out.mutable_position());
  vec(l.direction, out.mutable_direction());
  out.set_inner_cone_angle(l.inner_cone_angle);
  out.set_outer_cone_angle(l.outer_cone_angle);
  out.set_baked(entry.baked);
  out.set_name(l.name);
  return out;
}

}  // namespace lightlink::service
