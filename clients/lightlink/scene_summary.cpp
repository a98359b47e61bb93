#include "clients/lightlink/scene_summary.h"

#include <set>
#include <tuple>

#include <fmt/format.h>

namespace lightlink::cli {

nlohmann::ordered_json summarizeScene(const scene::Scene& s) {
  std::size_t static_meshes = 0, with_uv1 = 0, static_with_uv1 = 0;
  std::set<int> gltf_meshes;
  for (const auto& m : s.meshes) {
    gltf_meshes.insert(m.gltf_mesh);
    if (m.is_static) ++static_meshes;
    if (m.hasLightmapUv()) {
      ++with_uv1;
      if (m.is_static) ++static_with_uv1;
    }
  }
  std::size_t point = 0, spot = 0, directional = 0;
  for (const auto& l : s.lights) {
    switch (l.kind) {
      case scene::Light::Kind::kPoint: ++point; break;
      case scene::Light::Kind::kSpot: ++spot; break;
      case scene::Light::Kind::kDirectional: ++directional; break;
    }
  }
  std::size_t emissive_materials = 0, mask_materials = 0, blend_materials = 0;
  for (const auto& m : s.materials) {
    emissive_materials += m.isEmissive() ? 1 : 0;
    mask_materials += m.alpha_mode == scene::Material::AlphaMode::kMask ? 1 : 0;
    blend_materials += m.alpha_mode == scene::Material::AlphaMode::kBlend ? 1 : 0;
  }
  // Instances whose flags change what rays see (cut-outs, shadow and GI flags), named up to a few.
  constexpr std::size_t kNamed = 8;
  std::size_t cutout_instances = 0;
  nlohmann::ordered_json no_shadow = nlohmann::ordered_json::array(), no_gi = nlohmann::ordered_json::array();
  std::size_t no_shadow_count = 0, no_gi_count = 0;
  std::size_t receive[3] = {0, 0, 0};
  for (const auto& m : s.meshes) {
    const bool cut = m.material >= 0 && std::size_t(m.material) < s.materials.size() &&
                     s.materials[std::size_t(m.material)].hasCutout();
    cutout_instances += cut ? 1 : 0;
    if (!m.cast_shadows && no_shadow_count++ < kNamed) no_shadow.push_back(m.name);
    if (!m.contribute_gi && no_gi_count++ < kNamed) no_gi.push_back(m.name);
    if (m.is_static) ++receive[static_cast<int>(m.receive_gi)];
  }

  const std::size_t tris = s.triangleCount();
  const std::size_t static_tris = s.staticTriangleCount();
  nlohmann::ordered_json j;
  j["file"] = s.source_path;
  j["mesh_instances"] = s.meshes.size();
  j["gltf_meshes"] = gltf_meshes.size();
  j["static_mesh_instances"] = static_meshes;
  j["dynamic_mesh_instances"] = s.meshes.size() - static_meshes;
  j["triangles"] = tris;
  j["static_triangles"] = static_tris;
  j["dynamic_triangles"] = tris - static_tris;
  j["degenerate_triangles_dropped"] = s.stats.degenerate_dropped;
  j["materials"] = s.materials.size();
  j["emissive_materials"] = emissive_materials;
  j["alpha"] = {{"mask_materials", mask_materials},
                {"blend_materials", blend_materials},
                {"cutout_mesh_instances", cutout_instances}};
  j["cast_shadows_false"] = {{"mesh_instances", no_shadow_count}, {"names", no_shadow}};
  j["contribute_gi_false"] = {{"mesh_instances", no_gi_count}, {"names", no_gi}};
  // Static instances by receive_gi (before the unwrap moves objects too small for the
  // lightmap to the volume).
  j["receive_gi"] = {{"lightmap", receive[0]}, {"volume", receive[1]}, {"off", receive[2]}};
  j["lights"] = {{"point", point}, {"spot", spot}, {"directional", directional}};
  j["emissive_area_m2"] = s.emissiveArea();
  j["bounds_m"] = {{"min", {s.bounds.min.x, s.bounds.min.y, s.bounds.min.z}},
                   {"max", {s.bounds.max.x, s.bounds.max.y, s.bounds.max.z}}};
  j["scale_m"] = s.scale;
  j["lightmap_uv"] = {{"mesh_instances_with_uv1", with_uv1},
                      {"static_instances_with_uv1", static_with_uv1},
                      {"static_instances", static_meshes},
                      {"unwrap_needed", static_with_uv1 < static_meshes}};
  j["images"] = {{"decoded", s.stats.images_decoded},
                 {"skipped", s.stats.images_skipped},
                 {"decoded_bytes", s.stats.image_bytes}};
  j["warnings"] = s.warnings;
  return j;
}

std::string formatSummary(const nlohmann::ordered_json& j) {
  std::string out;
  auto line = [&out](const char* key, const std::string& value) {
    out += fmt::format("{:<12} {}\n", key, value);
  };
  line("scene", j["file"].get<std::string>());
  line("meshes", fmt::format("{} instances of {} meshes ({} static, {} dynamic)",
                             j["mesh_instances"].get<std::size_t>(), j["gltf_meshes"].get<std::size_t>(),
                             j["static_mesh_instances"].get<std::size_t>(),
                             j["dynamic_mesh_instances"].get<std::size_t>()));
  line("triangles", fmt::format("{} ({} static, {} dynamic), {} degenerate dropped",
                                j["triangles"].get<std::size_t>(), j["static_triangles"].get<std::size_t>(),
                                j["dynamic_triangles"].get<std::size_t>(),
                                j["degenerate_triangles_dropped"].get<std::size_t>()));
  line("materials", fmt::format("{} ({} emissive)", j["materials"].get<std::size_t>(),
                                j["emissive_materials"].get<std::size_t>()));
  const auto& a = j["alpha"];
  line("alpha", fmt::format("{} MASK, {} BLEND materials (cut out for every ray: {} instances)",
                            a["mask_materials"].get<std::size_t>(), a["blend_materials"].get<std::size_t>(),
                            a["cutout_mesh_instances"].get<std::size_t>()));
  for (const auto& [key, label, what] : {std::tuple{"cast_shadows_false", "no shadows", "cast no shadows"},
                                         std::tuple{"contribute_gi_false", "no GI", "reflect no bounce light"}}) {
    const auto& ns = j[key];
    if (const auto n = ns["mesh_instances"].get<std::size_t>(); n > 0) {
      std::string names;
      for (const auto& name : ns["names"]) names += (names.empty() ? "" : ", ") + name.get<std::string>();
      line(label, fmt::format("{} instances {}: {}{}", n, what, names, n > ns["names"].size() ? ", ..." : ""));
    }
  }
  const auto& rg = j["receive_gi"];
  line("receive GI", fmt::format("{} static instances from the lightmap, {} from the volume, {} off",
                                 rg["lightmap"].get<std::size_t>(), rg["volume"].get<std::size_t>(),
                                 rg["off"].get<std::size_t>()));
  const auto& l = j["lights"];
  line("lights", fmt::format("{} point, {} spot, {} directional; emissive area {:.6g} m^2",
                             l["point"].get<std::size_t>(), l["spot"].get<std::size_t>(),
                             l["directional"].get<std::size_t>(), j["emissive_area_m2"].get<double>()));
  const auto& mn = j["bounds_m"]["min"];
  const auto& mx = j["bounds_m"]["max"];
  line("bounds", fmt::format("[{:.4g}, {:.4g}, {:.4g}] .. [{:.4g}, {:.4g}, {:.4g}] m, diagonal {:.4g} m",
                             mn[0].get<double>(), mn[1].get<double>(), mn[2].get<double>(),
                             mx[0].get<double>(), mx[1].get<double>(), mx[2].get<double>(),
                             j["scale_m"].get<double>()));
  const auto& uv = j["lightmap_uv"];
  line("lightmap UV", fmt::format("{} of {} static instances have TEXCOORD_1{}",
                                  uv["static_instances_with_uv1"].get<std::size_t>(),
                                  uv["static_instances"].get<std::size_t>(),
                                  uv["unwrap_needed"].get<bool>() ? " (unwrap needed)" : ""));
  const auto& im = j["images"];
  line("images", fmt::format("{} decoded for lighting ({:.1f} MiB), {} not needed (normal, metallic, occlusion, unused)",
                             im["decoded"].get<std::size_t>(), im["decoded_bytes"].get<double>() / (1 << 20),
                             im["skipped"].get<std::size_t>()));
  const auto& w = j["warnings"];
  if (w.empty()) {
    line("warnings", "none");
  } else {
    line("warnings", fmt::format("{}", w.size()));
    for (const auto& msg : w) out += fmt::format("  - {}\n", msg.get<std::string>());
  }
  return out;
}

}  // namespace lightlink::cli
