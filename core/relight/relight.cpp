#include "core/relight/relight.h"

#include <memory>

#include "core/common/isa.h"
#include "core/relight/cache_lighting.h"
#include "core/relight/cpu_passes.h"
#include "core/relight/emission_state.h"
#include "core/relight/pipeline.h"
#include "core/relight/scene_tables.h"
#include "core/sh/sh.h"

namespace lightlink::relight {

// ---- effects plan --------------------------------------------------------------------

std::string EffectsPlan::toText() const {
  std::string s = "effects plan:\n";
  auto line = [&](const char* name, bool on) { s += fmt::format("  {:<13} {}\n", name, on ? "yes" : "skipped"); };
  line("punctual", punctual);
  line("emissive", emissive);
  line("sky", sky);
  line("grid", grid);
  s += fmt::format("  {:<13} {}\n", "bounces", bounces ? fmt::format("up to {}", max_bounces) : "skipped");
  line("baked direct", baked_direct);
  line("emitter direct", emissive_direct);
  for (const auto& r : reasons) s += "  - " + r + "\n";
  return s;
}

nlohmann::ordered_json EffectsPlan::toJson() const {
  return {{"punctual", punctual}, {"emissive", emissive},        {"sky", sky},
          {"grid", grid},         {"bounces", bounces},          {"max_bounces", max_bounces},
          {"baked_direct", baked_direct}, {"emissive_direct", emissive_direct}, {"reasons", reasons}};
}

double RelightResult::totalSeconds() const {
  double t = 0.0;
  for (const auto& s : timings) t += s.seconds;
  return t;
}

glm::vec3 RelightResult::lightmapIndirect(std::uint32_t texel, const glm::vec3& n) const {
  const int nc = coeffCount();
  const float* sh = lightmap_sh.data() + std::size_t(texel) * 3 * nc;
  return {sh::irradiance(bands, sh, n), sh::irradiance(bands, sh + nc, n), sh::irradiance(bands, sh + 2 * nc, n)};
}

nlohmann::ordered_json RelightResult::report() const {
  nlohmann::ordered_json j;
  j["version"] = version;
  j["backend"] = backend;
  j["kernel"] = kernel;
  j["link_form"] = linkFormName(link_form);
  j["bands"] = bands;
  j["lightmap"] = {{"width", width}, {"height", height}};
  j["effects_plan"] = plan.toJson();
  j["passes"] = {{"warm", passes.warm}, {"surfel_direct", passes.surfel_direct}, {"emission", passes.emission},
                 {"pulls", passes.pulls}, {"cache_lighting", passes.cache_lighting},
                 {"grid_lighting", passes.grid_lighting},
                 {"sky", passes.sky}, {"bounces", passes.bounces}, {"baked_direct", passes.baked_direct},
                 {"emissive_direct", passes.emissive_direct}, {"surfel_emitter", passes.surfel_emitter},
                 {"grid_emitter", passes.grid_emitter},
                 {"fill", passes.fill}, {"incremental", passes.incremental},
                 {"unchanged", passes.unchanged}};
  j["counts"] = {{"surfels", counts.surfels}, {"surfels_lit", counts.surfels_lit}, {"nodes", counts.nodes},
                 {"nodes_pulled", counts.nodes_pulled}, {"caches", counts.caches},
                 {"caches_summed", counts.caches_summed}, {"grid_caches", counts.grid_caches},
                 {"grid_caches_summed", counts.grid_caches_summed}, {"links_read", counts.links_read},
                 {"surfels_gathered", counts.surfels_gathered},
                 {"shadow_rays", counts.shadow_rays}, {"emitter_triangles", counts.emitter_triangles},
                 {"emitter_direct_reused", counts.emitter_direct_reused},
                 {"surfel_emitter_reused", counts.surfel_emitter_reused},
                 {"grid_emitter_reused", counts.grid_emitter_reused},
                 {"emitter_rescaled", counts.emitter_rescaled},
                 {"texels", counts.texels},
                 {"texels_filled", counts.texels_filled},
                 {"surfels_without_gather", counts.surfels_without_gather}};
  auto seamJson = [](const SeamStats& s) {
    return nlohmann::ordered_json{{"edges", s.edges},           {"samples", s.samples},
                                  {"texels", s.texels},         {"jump_before", s.jump_before},
                                  {"jump_after", s.jump_after}};
  };
  j["seams"] = {{"lightmap", seamJson(seams)}, {"direct", seamJson(direct_seams)}};
  nlohmann::ordered_json t = nlohmann::ordered_json::object();
  for (const auto& s : timings) t[s.stage] = s.seconds;
  t["total"] = totalSeconds();
  j["seconds"] = t;
  j["bounces"] = nlohmann::ordered_json::array();
  for (const auto& b : bounce_log)
    j["bounces"].push_back({{"bounce", b.bounce}, {"added_flux", b.added_flux}, {"total_flux", b.total_flux},
                            {"seconds", b.seconds}});
  j["bounce_stop"] = bounce_stop;
  j["warnings"] = warnings;
  return j;
}

// ---- Relighter: the pipeline with the CPU passes ------------------------------------------

struct Relighter::Impl {
  SceneTables tables;
  RelightPipeline pipeline;  // reads `tables`, declared first
  explicit Impl(SceneTables t) : tables(std::move(t)), pipeline(tables, makeCpuPasses(tables)) {}
};

Relighter::Relighter(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
Relighter::Relighter(Relighter&&) noexcept = default;
Relighter& Relighter::operator=(Relighter&&) noexcept = default;
Relighter::~Relighter() = default;

bool Relighter::simdAvailable() { return isaAtLeast(Isa::kAvx2); }

void Relighter::invalidate(Forget what) { impl_->pipeline.invalidate(what == Forget::kEverything); }

Expected<PullAreas> pullAreas(const precompute::Precomputation& p) {
  const std::size_t ns = p.surfels.size();
  const auto& t = p.tree;
  const auto& seen = p.surfel_seen;
  if (!seen.empty() && seen.size() != ns)
    return invalidInput("relight: {} seen flags for {} surfels", seen.size(), ns);
  if (t.nodeCount() != (ns ? 2 * ns - 1 : 0) || t.leaf_of_surfel.size() != ns)
    return invalidInput("relight: tree ({} nodes) does not match {} surfels", t.nodeCount(), ns);
  PullAreas out;
  out.surfel.resize(ns);
  for (std::size_t s = 0; s < ns; ++s) {
    const bool counts = seen.empty() || seen[s] != 0;
    out.surfel[s] = counts ? p.surfels.area[s] : 0.0f;
    out.unseen += counts ? 0 : 1;
  }
  // Summed bottom-up in double and rounded once per node, exactly as tree.area is
  // (hierarchy/tree.cpp): with every surfel seen these are tree.area, bit for bit.
  const std::size_t nodes = t.nodeCount();
  std::vector<double> area(nodes, 0.0);
  for (std::size_t s = 0; s < ns; ++s) {
    if (t.leaf_of_surfel[s] >= nodes)
      return invalidInput("relight: surfel {} names leaf {} of {} nodes", s, t.leaf_of_surfel[s], nodes);
    area[t.leaf_of_surfel[s]] = out.surfel[s];
  }
  out.inv_node.resize(nodes);
  for (std::size_t n = nodes; n-- > 0;) {
    if (t.left[n] >= 0) area[n] = area[std::size_t(t.left[n])] + area[std::size_t(t.right[n])];
    const float a = float(area[n]);
    out.inv_node[n] = a > 0.0f ? 1.0f / a : 0.0f;
  }
  return out;
}

Expected<Relighter> Relighter::create(const scene::Scene& scene, const rt::Accel& accel,
                                      const precompute::Precomputation& p) {
  return create(scene, accel, p, p.lightmap_links.view(), p.grid_links.view());
}

Expected<Relighter> Relighter::create(const scene::Scene& scene, const rt::Accel& accel,
                                      const precompute::Precomputation& p, links::LinksView lm,
                                      links::LinksView grid) {
  auto tables = SceneTables::build(scene, accel, p, lm, grid);
  if (!tables) return tables.status();
  return Relighter(std::make_unique<Impl>(std::move(*tables)));
}

EffectsPlan Relighter::plan(const LightSet& lights, const RelightOptions& options) const {
  return impl_->pipeline.plan(lights, options);
}

bool Relighter::incrementalFor(const LightSet& lights, const RelightOptions& options) const {
  return impl_->pipeline.incrementalFor(lights, options);
}

Expected<RelightResult> Relighter::relight(const LightSet& lights, const RelightOptions& o) {
  RelightResult res;
  if (Status s = relightInto(lights, o, res); !s) return s;
  return res;
}

Status Relighter::relightInto(const LightSet& lights, const RelightOptions& o, RelightResult& res) {
  return impl_->pipeline.relightInto(lights, o, res);
}

void Relighter::surfelEmission(const LightSet& lights, std::vector<glm::vec3>& out) const {
  surfelEmissionInto(impl_->tables, lights, out);
}

Relighter::GatherTables Relighter::gatherTables() const {
  const SceneTables& t = impl_->tables;
  return {t.gather_begin, t.gather_cache, t.gather_weight, t.gather_from_grid, t.lm_has_value, t.grid_has_value,
          t.surfels_without_gather};
}

}  // namespace lightlink::relight
