#include "core/scene/surface_rules.h"

#include <fmt/format.h>
#include <nlohmann/json.hpp>

namespace lightlink::scene {
namespace {

constexpr const char* kReceiveGiNames[] = {"lightmap", "volume", "off"};

Expected<int> flag(const nlohmann::json& v, std::string_view origin, std::size_t i, const char* key) {
  if (!v.is_boolean()) return invalidInput("{}: surfaces[{}].{} must be true or false", origin, i, key);
  return v.get<bool>() ? 1 : 0;
}

}  // namespace

bool globMatch(std::string_view pattern, std::string_view text) {
  // Iterative wildcard match with one backtrack point (the last *): linear in practice.
  std::size_t p = 0, t = 0, star = std::string_view::npos, mark = 0;
  while (t < text.size()) {
    if (p < pattern.size() && (pattern[p] == '?' || pattern[p] == text[t])) {
      ++p, ++t;
    } else if (p < pattern.size() && pattern[p] == '*') {
      star = p++, mark = t;
    } else if (star != std::string_view::npos) {
      p = star + 1, t = ++mark;
    } else {
      return false;
    }
  }
  while (p < pattern.size() && pattern[p] == '*') ++p;
  return p == pattern.size();
}

Expected<SurfaceRules> parseSurfaceRules(std::string_view json, std::string_view origin) {
  const nlohmann::json j = nlohmann::json::parse(json, nullptr, /*allow_exceptions=*/false);
  if (j.is_discarded()) return invalidInput("{}: not valid JSON", origin);
  if (!j.is_object()) return invalidInput("{}: expected a JSON object with \"version\" and \"surfaces\"", origin);
  for (const auto& [key, value] : j.items())
    if (key != "version" && key != "surfaces")
      return invalidInput("{}: unknown key '{}' (expected \"version\" and \"surfaces\")", origin, key);
  const auto version = j.find("version");
  if (version == j.end() || !version->is_number_integer())
    return invalidInput("{}: \"version\" (an integer) is required", origin);
  if (version->get<long long>() != 1)
    return invalidInput("{}: surface rules version {} is not supported (this build reads 1)", origin, version->dump());
  const auto list = j.find("surfaces");
  if (list == j.end() || !list->is_array()) return invalidInput("{}: \"surfaces\" must be an array of rules", origin);
  if (list->size() > 4096) return invalidInput("{}: {} rules exceed 4096", origin, list->size());
  SurfaceRules out;
  for (std::size_t i = 0; i < list->size(); ++i) {
    const nlohmann::json& r = (*list)[i];
    if (!r.is_object()) return invalidInput("{}: surfaces[{}] must be an object", origin, i);
    SurfaceRule rule;
    for (const auto& [key, value] : r.items()) {
      if (key == "mesh" || key == "material") {
        if (!value.is_string() || value.get<std::string>().empty() || value.get<std::string>().size() > 1024)
          return invalidInput("{}: surfaces[{}].{} must be a non-empty name pattern (at most 1024 characters)", origin,
                              i, key);
        (key == "mesh" ? rule.mesh : rule.material) = value.get<std::string>();
      } else if (key == "cast_shadows" || key == "contribute_gi") {
        auto f = flag(value, origin, i, key.c_str());
        if (!f) return f.status();
        (key == "cast_shadows" ? rule.cast_shadows : rule.contribute_gi) = *f;
      } else if (key == "receive_gi") {
        const std::string s = value.is_string() ? value.get<std::string>() : std::string();
        for (int k = 0; k < 3; ++k)
          if (s == kReceiveGiNames[k]) rule.receive_gi = k;
        if (rule.receive_gi < 0)
          return invalidInput("{}: surfaces[{}].receive_gi must be \"lightmap\", \"volume\" or \"off\"", origin, i);
      } else {
        return invalidInput(
            "{}: surfaces[{}] has unknown key '{}' (known: mesh, material, cast_shadows, contribute_gi, receive_gi)",
            origin, i, key);
      }
    }
    if (rule.mesh.empty() && rule.material.empty())
      return invalidInput("{}: surfaces[{}] selects nothing: give \"mesh\" and/or \"material\"", origin, i);
    if (rule.cast_shadows < 0 && rule.contribute_gi < 0 && rule.receive_gi < 0)
      return invalidInput("{}: surfaces[{}] sets no flag (cast_shadows, contribute_gi, receive_gi)", origin, i);
    out.rules.push_back(std::move(rule));
  }
  return out;
}

std::string SurfaceRules::canonical() const {
  nlohmann::ordered_json list = nlohmann::ordered_json::array();
  for (const SurfaceRule& r : rules) {
    nlohmann::ordered_json o;
    if (!r.mesh.empty()) o["mesh"] = r.mesh;
    if (!r.material.empty()) o["material"] = r.material;
    if (r.cast_shadows >= 0) o["cast_shadows"] = r.cast_shadows == 1;
    if (r.contribute_gi >= 0) o["contribute_gi"] = r.contribute_gi == 1;
    if (r.receive_gi >= 0) o["receive_gi"] = kReceiveGiNames[r.receive_gi];
    list.push_back(std::move(o));
  }
  return nlohmann::ordered_json{{"version", 1}, {"surfaces", std::move(list)}}.dump();
}

std::vector<std::size_t> applySurfaceRules(Scene& scene, const SurfaceRules& rules) {
  std::vector<std::size_t> selected(rules.rules.size(), 0);
  for (std::size_t k = 0; k < rules.rules.size(); ++k) {
    const SurfaceRule& r = rules.rules[k];
    for (MeshInstance& m : scene.meshes) {
      if (!r.mesh.empty()) {
        const std::string_view full = m.name;
        const std::size_t slash = full.rfind('/');
        const bool hit = globMatch(r.mesh, full) || (slash != std::string_view::npos && globMatch(r.mesh, full.substr(0, slash)));
        if (!hit) continue;
      }
      if (!r.material.empty() && !globMatch(r.material, scene.materialOf(m).name)) continue;
      ++selected[k];
      if (r.cast_shadows >= 0) m.cast_shadows = r.cast_shadows == 1;
      if (r.contribute_gi >= 0) m.contribute_gi = r.contribute_gi == 1;
      if (r.receive_gi >= 0) {
        m.receive_gi = static_cast<ReceiveGi>(r.receive_gi);
        m.probe_lit = m.receive_gi != ReceiveGi::kLightmap;
      }
    }
    if (selected[k] == 0)
      scene.warnings.push_back(fmt::format("surface rule {} (mesh '{}', material '{}') selects no mesh instance", k,
                                           r.mesh.empty() ? "*" : r.mesh, r.material.empty() ? "*" : r.material));
  }
  return selected;
}

}  // namespace lightlink::scene
