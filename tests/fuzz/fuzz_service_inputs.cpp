#include "tests/fuzz/fuzz_service_inputs.h"

#include <set>

#include <nlohmann/json.hpp>

#include "clients/client/light_update.h"
#include "proto/lightlink.pb.h"
#include "service/validation.h"
#include "tests/fuzz/fuzz_inputs.h"

namespace lightlink::fuzz {
namespace {

// Validation passed: the new lights must relight (the update worker's next step).
void relightAccepted(const relight::LightSet& lights, RequestVerdict& v) {
  v.relit = true;
  v.relight = relightFuzzScene(lights);
}

// As SceneRegistry::openResident, minus the scene: options, backend, then the light-set
// JSON merged over the scene's lights with its emissive materials checked.
void openScene(const v1::OpenSceneRequest& r, RequestVerdict& v) {
  auto options = service::precomputeOptionsFrom(r);
  if (!options) {
    v.validation = options.status();
    return;
  }
  if (!v1::Backend_IsValid(r.backend())) {
    v.validation = invalidInput("backend: {} is not a Backend", static_cast<int>(r.backend()));
    return;
  }
  if (r.lightset_json().empty()) return;
  const nlohmann::json overrides = nlohmann::json::parse(r.lightset_json(), nullptr, /*allow_exceptions=*/false);
  if (overrides.is_discarded() || !overrides.is_object()) {
    v.validation = invalidInput("lightset_json: not a JSON object");
    return;
  }
  relight::LightSet lights = fuzzSceneLights();
  if (Status s = lights.apply(overrides); !s) {
    v.validation = s;
    return;
  }
  if (Status s = lights.checkMaterials(fuzzSceneMaterialCount()); !s) {
    v.validation = s;
    return;
  }
  relightAccepted(lights, v);
}

void updateLights(const v1::UpdateLightsRequest& r, RequestVerdict& v) {
  relight::LightSet lights = fuzzSceneLights();  // the copy the session swaps in on success
  v.validation = service::applyUpdate(r, fuzzSceneMaterialCount(), lights);
  if (v.validation) relightAccepted(lights, v);
}

template <typename Message>
bool parse(std::span<const std::uint8_t> bytes, Message& m) {
  return m.ParseFromArray(bytes.data(), static_cast<int>(bytes.size()));
}

// The kind byte also carries the bands of the result a ResultSpec is checked against.
std::vector<std::uint8_t> withKind(RequestKind kind, const google::protobuf::MessageLite& m, int result_bands = 1) {
  const int count = static_cast<int>(RequestKind::kCount);
  std::vector<std::uint8_t> out{static_cast<std::uint8_t>(static_cast<int>(kind) + count * (result_bands - 1))};
  const std::string bytes = m.SerializeAsString();
  out.insert(out.end(), bytes.begin(), bytes.end());
  return out;
}

void setVec(v1::Vec3* v, float x, float y, float z) {
  v->set_x(x);
  v->set_y(y);
  v->set_z(z);
}

}  // namespace

RequestVerdict applyRequestBytes(std::span<const std::uint8_t> bytes) {
  RequestVerdict v;
  if (bytes.empty()) return v;
  const auto kind = static_cast<RequestKind>(bytes[0] % static_cast<std::uint8_t>(RequestKind::kCount));
  const int result_bands = 1 + (bytes[0] / static_cast<std::uint8_t>(RequestKind::kCount)) % 4;
  const std::span<const std::uint8_t> body = bytes.subspan(1);
  // Bytes that do not parse never reach a handler: gRPC answers INTERNAL/INVALID_ARGUMENT.
  switch (kind) {
    case RequestKind::kOpenScene: {
      v1::OpenSceneRequest r;
      if ((v.parsed = parse(body, r))) openScene(r, v);
      break;
    }
    case RequestKind::kUpdateLights: {
      v1::UpdateLightsRequest r;
      if ((v.parsed = parse(body, r))) updateLights(r, v);
      break;
    }
    case RequestKind::kRelight: {
      v1::RelightRequest r;
      if ((v.parsed = parse(body, r))) v.validation = service::validateSpec(r.spec(), result_bands);
      break;
    }
    case RequestKind::kGetTextures: {
      v1::GetTexturesRequest r;
      if ((v.parsed = parse(body, r))) v.validation = service::validateSpec(r.spec(), result_bands);
      break;
    }
    case RequestKind::kSubscribe: {
      v1::SubscribeRequest r;
      if ((v.parsed = parse(body, r))) v.validation = service::validateSpec(r.spec(), result_bands);
      break;
    }
    case RequestKind::kCount: break;
  }
  return v;
}

RequestVerdict lightSetThroughClient(std::span<const std::uint8_t> bytes) {
  RequestVerdict v;
  const std::string text(bytes.begin(), bytes.end());
  std::set<std::string> known;
  for (const auto& l : fuzzSceneLights().lights()) known.insert(l.id);
  const std::set<std::string>* const id_views[2] = {nullptr, &known};
  for (const std::set<std::string>* ids : id_views) {
    auto update = client::LightUpdate::fromLightSetText(text, ids);
    if (!update) {
      v.validation = update.status();
      continue;
    }
    v.parsed = true;
    // The proto survives the wire (serialize, parse) before the daemon sees it.
    v1::UpdateLightsRequest wire;
    if (!wire.ParseFromString(update->proto().SerializeAsString())) {
      v.validation = internalError("a request LightUpdate built does not parse back");
      return v;
    }
    updateLights(wire, v);
    if (v.relit && !v.relight) return v;
  }
  return v;
}

std::vector<std::pair<std::string, std::vector<std::uint8_t>>> requestSeeds() {
  std::vector<std::pair<std::string, std::vector<std::uint8_t>>> seeds;
  {
    v1::OpenSceneRequest r;
    r.set_path("scenes/room.glb");
    r.set_preset("draft");
    r.set_surfels(4096);
    r.set_links(64);
    r.set_bands(2);
    r.set_rays(256);
    r.set_grid_spacing(0.5f);
    r.set_texel_size(0.05f);
    r.set_hierarchy("fast");
    r.set_backend(v1::BACKEND_CPU);
    r.set_name("fuzz");
    r.set_lightset_json(R"({"version": 1, "lights": [{"id": "bulb", "intensity": 9},)"
                        R"( {"id": "sun", "type": "directional", "direction": [0, -1, 0.2], "intensity": 3}],)"
                        R"( "sky": {"radiance": [0.1, 0.2, 0.3]}, "emissive": [{"material": 1, "scale": 2}]})");
    seeds.emplace_back("open_scene.bin", withKind(RequestKind::kOpenScene, r));
  }
  {
    v1::UpdateLightsRequest r;
    r.mutable_scene()->set_scene_id("s1");
    r.mutable_scene()->set_token("t");
    v1::Light* m = r.add_modify();
    m->set_id("bulb");
    m->set_intensity(12.0f);
    setVec(m->mutable_position(), 1.0f, 1.5f, 1.0f);
    v1::Light* a = r.add_add();
    a->set_id("spot");
    a->set_type(v1::LIGHT_TYPE_SPOT);
    setVec(a->mutable_position(), 1.0f, 1.8f, 1.0f);
    setVec(a->mutable_direction(), 0.0f, -1.0f, 0.0f);
    setVec(a->mutable_color(), 1.0f, 0.9f, 0.8f);
    a->set_intensity(30.0f);
    a->set_range(5.0f);
    a->set_inner_cone_angle(0.3f);
    a->set_outer_cone_angle(0.6f);
    a->set_baked(true);
    v1::Light* d = r.add_add();
    d->set_id("sun");
    d->set_type(v1::LIGHT_TYPE_DIRECTIONAL);
    setVec(d->mutable_direction(), 0.2f, -1.0f, 0.1f);
    d->set_intensity(2.0f);
    v1::EmissiveOverride* e = r.add_emissive();
    e->set_material(1);
    setVec(e->mutable_scale(), 2.0f, 2.0f, 2.0f);
    setVec(r.mutable_sky()->mutable_radiance(), 0.1f, 0.1f, 0.2f);
    r.set_emissive_baked(true);
    r.set_wait_ms(100);
    seeds.emplace_back("update_lights.bin", withKind(RequestKind::kUpdateLights, r));
    v1::UpdateLightsRequest replace;
    replace.set_replace_lights(true);
    v1::Light* p = replace.add_add();
    p->set_id("bulb");
    p->set_type(v1::LIGHT_TYPE_POINT);
    setVec(p->mutable_position(), 1.0f, 1.0f, 1.0f);
    p->set_intensity(4.0f);
    replace.add_emissive()->set_material(1);
    setVec(replace.mutable_emissive(0)->mutable_radiance(), 3.0f, 2.0f, 1.0f);
    for (int i = 0; i < 9; ++i) setVec(replace.mutable_sky()->add_sh(), 0.1f / float(i + 1), 0.0f, 0.05f);
    seeds.emplace_back("update_replace.bin", withKind(RequestKind::kUpdateLights, replace));
    v1::UpdateLightsRequest remove;
    remove.add_remove("bulb");
    seeds.emplace_back("update_remove.bin", withKind(RequestKind::kUpdateLights, remove));
  }
  {
    v1::ResultSpec spec;
    spec.set_skip_grid(true);
    spec.set_bands(2);
    spec.set_component(v1::COMPONENT_INDIRECT);
    spec.set_precision(v1::PRECISION_FLOAT);
    v1::RelightRequest relight;
    *relight.mutable_spec() = spec;
    relight.set_version(3);
    seeds.emplace_back("relight.bin", withKind(RequestKind::kRelight, relight, 3));
    v1::GetTexturesRequest textures;
    *textures.mutable_spec() = spec;
    textures.set_last_seen_version(1);
    seeds.emplace_back("get_textures.bin", withKind(RequestKind::kGetTextures, textures, 2));
    v1::SubscribeRequest subscribe;
    *subscribe.mutable_spec() = spec;
    subscribe.set_deltas(true);
    seeds.emplace_back("subscribe.bin", withKind(RequestKind::kSubscribe, subscribe, 4));
  }
  return seeds;
}

}  // namespace lightlink::fuzz
