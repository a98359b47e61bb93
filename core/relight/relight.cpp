#include "core/relight/relight.h"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstring>
#include <numbers>
#include <optional>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "core/common/check.h"
#include "core/relight/cache_lighting.h"
#include "core/relight/direct_layer.h"
#include "core/relight/direct_points.h"
#include "core/relight/emitter_direct.h"
#include "core/relight/indirect_smooth.h"
#include "core/common/sampling.h"
#include "core/scene/light_eval.h"
#include "core/sh/sh.h"

namespace lightlink::relight {
namespace {

using detail::forChunks;
using detail::kCacheChunk;
using detail::kChunk;
using detail::lightEmits;
using detail::reaches;
using detail::sameEmissive;
using detail::shadowedLight;

constexpr float kPi = std::numbers::pi_v<float>;
using Clock = std::chrono::steady_clock;
double secondsSince(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

// Gauss-Legendre nodes/weights on [-1, 1] by Newton iteration on P_n.
void gaussLegendre(int n, std::vector<double>& x, std::vector<double>& w) {
  x.resize(n), w.resize(n);
  for (int i = 0; i < n; ++i) {
    double z = std::cos(std::numbers::pi * (i + 0.75) / (n + 0.5)), dp = 0.0;
    for (int it = 0; it < 100; ++it) {
      double p0 = 1.0, p1 = z;
      for (int k = 2; k <= n; ++k) {
        const double p2 = ((2.0 * k - 1.0) * z * p1 - (k - 1.0) * p0) / k;
        p0 = p1, p1 = p2;
      }
      dp = n * (z * p1 - p0) / (z * z - 1.0);
      const double dz = p1 / dp;
      z -= dz;
      if (std::abs(dz) < 1e-15) break;
    }
    x[i] = z;
    w[i] = 2.0 / ((1.0 - z * z) * dp * dp);
  }
}

}  // namespace

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
  j["passes"] = {{"surfel_direct", passes.surfel_direct}, {"emission", passes.emission}, {"pulls", passes.pulls},
                 {"cache_lighting", passes.cache_lighting}, {"grid_lighting", passes.grid_lighting},
                 {"sky", passes.sky}, {"bounces", passes.bounces}, {"baked_direct", passes.baked_direct},
                 {"emissive_direct", passes.emissive_direct}, {"surfel_emitter", passes.surfel_emitter},
                 {"grid_emitter", passes.grid_emitter},
                 {"fill", passes.fill}, {"incremental", passes.incremental},
                 {"unchanged", passes.unchanged}};
  j["counts"] = {{"surfels", counts.surfels}, {"surfels_lit", counts.surfels_lit}, {"nodes", counts.nodes},
                 {"nodes_pulled", counts.nodes_pulled}, {"caches", counts.caches},
                 {"caches_summed", counts.caches_summed}, {"grid_caches", counts.grid_caches},
                 {"grid_caches_summed", counts.grid_caches_summed}, {"links_read", counts.links_read},
                 {"shadow_rays", counts.shadow_rays}, {"emitter_triangles", counts.emitter_triangles},
                 {"emitter_direct_reused", counts.emitter_direct_reused},
                 {"surfel_emitter_reused", counts.surfel_emitter_reused},
                 {"grid_emitter_reused", counts.grid_emitter_reused},
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

// ---- Relighter -----------------------------------------------------------------------

struct Relighter::Impl {
  const scene::Scene& scene;
  const rt::Accel& accel;
  const precompute::Precomputation& p;
  links::LinksView lm_links, grid_links;
  bool simd = false;

  // Static per-surfel data (tree order).
  std::vector<int> surfel_material;
  // Bounce gather: up to 4 (lightmap) or 8 (grid) weighted caches per surfel, CSR.
  std::vector<std::uint32_t> gather_begin, gather_cache;
  std::vector<float> gather_weight;
  std::vector<std::uint8_t> gather_from_grid;
  std::size_t surfels_without_gather = 0;
  // Some surfel gathers from the grid: bounce passes must then light the grid each time,
  // otherwise only the last pass's grid values are used (output).
  bool grid_gathered = false;
  std::vector<std::uint8_t> lm_has_value, grid_has_value;  // valid or filled
  // Every output texel as a weighted sum of lightmap caches: a texel with a cache is that
  // cache, a dilated texel the dilation plan's averages flattened to caches (they are fixed
  // per precomputation), so writing the texels is one parallel gather, not a serial pass
  // over the dilation plan. Texels without an entry are empty (invalid, zero).
  detail::TexelMap texel_map;
  // The finer direct layer when the precomputation has one: then the caches carry no direct.
  DirectLayer layer;
  SeamStitch seams;  // of the lightmap atlas
  // The smooth_indirect filter, built on first use (its weights are ~9 entries per texel).
  std::optional<detail::IndirectSmooth> smooth;
  std::vector<float> smooth_scratch;
  PullAreas pull;  // leaf areas and node inverse areas of the pull (pullAreas)

  // Per-relight state, kept for incremental updates.
  std::vector<scene::Light> last_lights;       // parallel to per_light_surfel
  std::vector<std::string> last_ids;
  std::vector<std::uint8_t> last_baked;
  std::vector<std::vector<glm::vec3>> per_light_surfel;  // E per surfel per light (lux)
  std::vector<std::vector<glm::vec3>> per_light_cache;   // baked direct E per lightmap cache
  std::vector<EmissiveOverride> last_emissive;
  bool last_emissive_baked = true;
  Sky last_sky;
  RelightOptions last_options;
  bool last_valid = false;
  bool last_bounced = false;
  std::vector<BounceRecord> last_bounce_log;  // re-reported when nothing changed
  std::string last_bounce_stop;

  // Surfel radiosity is kept in two parts, emitted pi * L_e and reflected rho * E, because every
  // cache gathers only the reflected part through its links: the emitters' direct light is
  // sampled on the emitting triangles instead (into `direct` for texels, grid_emit for grid
  // caches), which a coarse cut node cannot blur.
  std::vector<glm::vec3> emission_b;   // pi * L_emit per surfel (after overrides)
  std::vector<glm::vec3> direct_e;     // sum of per-light E per surfel, in light order, + surfel_emit
  // The emitters' direct irradiance per surfel (empty when nothing emits), sampled on the
  // emitting triangles. Surfels used to receive it through the first bounce gather from the
  // lightmap caches' links, which lose a small bright emitter in coarse cut nodes and 3-band
  // SH: that gather gave the surfels 0.72 of the reference's emitter light on the Cornell box
  // (bench/accuracy/stage_probe, docs/quality.md). Kept while the emission state is.
  std::vector<glm::vec3> surfel_emit;
  bool surfel_emit_valid = false;
  std::vector<EmissiveOverride> surfel_emit_overrides;
  std::vector<glm::vec3> b0, b;        // reflected radiosity rho * E without / with indirect
  std::vector<float> flux[3];          // reflected flux per node, planar (the pull adds channel by channel)
  std::vector<float> rad_rgbx;         // reflected node radiosity, (R, G, B, 0): what the kernels read
  std::vector<float> lm_sh, grid_sh;   // per cache, 3 * nc: reflected light and sky (links)
  std::vector<glm::vec3> cache_direct; // per lightmap cache
  std::vector<glm::vec3> emitter_cache;  // emitter direct E per lightmap cache; empty when not baked
  // What emitter_cache was computed for: it depends only on the static scene, the emissive
  // overrides and the sample count, so full relights that change only punctual lights, sky or
  // bounces reuse it (the pass costs N shadow rays per texel, the bulk of a relight).
  bool emitter_valid = false;
  std::vector<EmissiveOverride> emitter_overrides;
  int emitter_samples = 0;
  std::size_t emitter_triangles = 0;
  // The emitters' radiance SH per grid cache (3 * nc each, filled; empty when nothing emits),
  // added to grid_sh in the output only, so bounce gathers from the grid see reflected light
  // as they do from the lightmap. Depends on the emission state and the band count alone.
  std::vector<float> grid_emit;
  bool grid_emit_valid = false;
  std::vector<EmissiveOverride> grid_emit_overrides;
  int grid_emit_bands = 0;
  std::vector<float> sky_matrix[3];    // nc_out x nc_links per channel

  // Inverted index node -> caches (lazily built, for incremental relights).
  bool inverted_built = false;
  std::vector<std::uint32_t> lm_inv_begin, lm_inv, grid_inv_begin, grid_inv;

  Impl(const scene::Scene& s, const rt::Accel& a, const precompute::Precomputation& pc, links::LinksView lm,
       links::LinksView grid)
      : scene(s), accel(a), p(pc), lm_links(lm), grid_links(grid), layer(s, a, pc) {}

  void buildGather();
  void buildInverted();
  EffectsPlan makePlan(const LightSet& lights, const RelightOptions& o) const;
  void computeEmission(const LightSet& lights);
  void lightSurfels(const scene::Light& light, std::vector<glm::vec3>& out, const std::vector<std::uint32_t>* subset,
                    std::size_t& rays) const;
  void bakedDirect(const scene::Light& light, std::vector<glm::vec3>& out,
                   const std::vector<std::uint32_t>* subset, std::size_t& rays) const;
  void emitterDirect(const LightSet& lights, int samples, RelightCounts& counts);
  void setLeafFlux(std::size_t s);
  void pullAll();
  void lightCaches(const links::LinksView& view, std::vector<float>& out, const std::vector<std::uint8_t>& valid,
                   const std::vector<std::uint32_t>* subset, int bands, LinkForm form, bool sky, const float* rad);
  void buildSkyMatrix(const Sky& sky, int bands_out, int bands_links);
  void applyFill(const caches::FillPlan& plan, float* data, std::size_t stride) const {
    detail::applyFill(plan, data, stride);
  }
};

Relighter::Relighter(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
Relighter::Relighter(Relighter&&) noexcept = default;
Relighter& Relighter::operator=(Relighter&&) noexcept = default;
Relighter::~Relighter() = default;

bool Relighter::simdAvailable() { return detail::cpuSupportsAvx2F16c(); }

void Relighter::invalidate(Forget what) {
  impl_->last_valid = false;
  impl_->layer.invalidate(what == Forget::kEverything);
  if (what == Forget::kEverything)
    impl_->emitter_valid = false, impl_->surfel_emit_valid = false, impl_->grid_emit_valid = false;
}

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
  const std::size_t ns = p.surfels.size();
  if (p.tree.surfelCount() != ns || p.tree.nodeCount() != (ns ? 2 * ns - 1 : 0))
    return invalidInput("relight: tree ({} surfels, {} nodes) does not match {} surfels", p.tree.surfelCount(),
                        p.tree.nodeCount(), ns);
  if (lm.cacheCount() != p.lightmap.size())
    return invalidInput("relight: lightmap links cover {} caches, the precomputation has {}", lm.cacheCount(),
                        p.lightmap.size());
  if (p.has_grid && grid.cacheCount() != p.grid.size())
    return invalidInput("relight: grid links cover {} caches, the grid has {}", grid.cacheCount(), p.grid.size());
  if (lm.bands < 1 || lm.bands > sh::kMaxBands) return invalidInput("relight: link bands {} not in 1..4", lm.bands);
  for (std::size_t i = 0; i < ns; ++i)
    if (p.surfels.mesh[i] >= scene.meshes.size())
      return invalidInput("relight: surfel {} names mesh {} of a scene with {} meshes", i, p.surfels.mesh[i],
                          scene.meshes.size());
  auto pull = pullAreas(p);
  if (!pull) return pull.status();
  auto impl = std::make_unique<Impl>(scene, accel, p, lm, grid);
  impl->pull = std::move(pull).value();
  impl->simd = detail::cpuSupportsAvx2F16c();
  impl->surfel_material.resize(ns);
  for (std::size_t i = 0; i < ns; ++i) impl->surfel_material[i] = scene.meshes[p.surfels.mesh[i]].material;
  impl->buildGather();
  impl->texel_map = detail::buildTexelMap(p.lightmap.cache_of_texel, impl->lm_has_value, p.dilation);
  impl->seams = SeamStitch::build(scene, p.lightmap.width, p.lightmap.height);
  const std::size_t nodes = p.tree.nodeCount();
  // The AVX2 runtime kernel gathers with 32-bit offsets 4 * node.
  if (nodes >= (std::size_t(1) << 29)) return invalidInput("relight: {} tree nodes exceed 2^29", nodes);
  for (int ch = 0; ch < 3; ++ch) impl->flux[ch].assign(nodes, 0.0f);
  impl->rad_rgbx.assign(4 * nodes, 0.0f);
  return Relighter(std::move(impl));
}

void Relighter::Impl::buildGather() {
  // Which caches hold a value after the fill: valid ones and fill targets with sources.
  lm_has_value = detail::hasValue(p.lightmap.valid, p.lightmap_fill);
  if (p.has_grid) grid_has_value = detail::hasValue(p.grid.valid, p.grid_fill);

  const std::size_t ns = p.surfels.size();
  const int w = p.lightmap.width, h = p.lightmap.height;
  gather_begin.assign(1, 0);
  gather_from_grid.assign(ns, 0);
  surfels_without_gather = 0;
  auto texelCache = [&](int x, int y) -> std::int32_t {
    if (x < 0 || y < 0 || x >= w || y >= h) return -1;
    const std::int32_t c = p.lightmap.cache_of_texel[std::size_t(y) * w + x];
    return c >= 0 && lm_has_value[c] ? c : -1;
  };
  for (std::size_t s = 0; s < ns; ++s) {
    const glm::vec2 uv = p.surfels.lightmap_uv[s];
    std::size_t added = 0;
    if (w > 0 && uv.x >= 0.0f && uv.y >= 0.0f) {
      // Texel (x, y) covers [x, x + 1) in uv * resolution, its centre is at x + 0.5.
      const float fx = uv.x * w - 0.5f, fy = uv.y * h - 0.5f;
      const int x0 = int(std::floor(fx)), y0 = int(std::floor(fy));
      const float tx = fx - x0, ty = fy - y0;
      float wsum = 0.0f;
      const std::size_t start = gather_cache.size();
      for (int dy = 0; dy < 2; ++dy)
        for (int dx = 0; dx < 2; ++dx) {
          const std::int32_t c = texelCache(x0 + dx, y0 + dy);
          const float wt = (dx ? tx : 1.0f - tx) * (dy ? ty : 1.0f - ty);
          if (c < 0 || wt <= 0.0f) continue;
          gather_cache.push_back(std::uint32_t(c));
          gather_weight.push_back(wt);
          wsum += wt;
        }
      if (wsum > 0.0f) {
        for (std::size_t k = start; k < gather_cache.size(); ++k) gather_weight[k] /= wsum;
        added = gather_cache.size() - start;
      } else {
        // Nearest texel with a value within 2 texels (a surfel in a chart's gutter corner).
        float best = 1e30f;
        std::int32_t best_c = -1;
        const int cx = int(std::floor(uv.x * w)), cy = int(std::floor(uv.y * h));
        for (int dy = -2; dy <= 2; ++dy)
          for (int dx = -2; dx <= 2; ++dx) {
            const std::int32_t c = texelCache(cx + dx, cy + dy);
            const float d = float(dx * dx + dy * dy);
            if (c >= 0 && d < best) best = d, best_c = c;
          }
        if (best_c >= 0) {
          gather_cache.push_back(std::uint32_t(best_c));
          gather_weight.push_back(1.0f);
          added = 1;
        }
      }
    }
    if (added == 0 && p.has_grid && p.grid.spacing_m > 0.0f) {
      // Trilinear over the grid caches that hold a value.
      const glm::vec3 g = (p.surfels.position[s] - p.grid.origin) / p.grid.spacing_m;
      const glm::ivec3 i0 = glm::clamp(glm::ivec3(glm::floor(g)), glm::ivec3(0), glm::max(p.grid.dims - 2, 0));
      const glm::vec3 t = glm::clamp(g - glm::vec3(i0), 0.0f, 1.0f);
      float wsum = 0.0f;
      const std::size_t start = gather_cache.size();
      for (int c = 0; c < 8; ++c) {
        const glm::ivec3 o(c & 1, (c >> 1) & 1, (c >> 2) & 1);
        const glm::ivec3 q = glm::min(i0 + o, p.grid.dims - 1);
        const std::size_t idx = (std::size_t(q.z) * p.grid.dims.y + q.y) * p.grid.dims.x + q.x;
        const float wt = (o.x ? t.x : 1 - t.x) * (o.y ? t.y : 1 - t.y) * (o.z ? t.z : 1 - t.z);
        if (!grid_has_value[idx] || wt <= 0.0f) continue;
        gather_cache.push_back(std::uint32_t(idx));
        gather_weight.push_back(wt);
        wsum += wt;
      }
      if (wsum > 0.0f) {
        for (std::size_t k = start; k < gather_cache.size(); ++k) gather_weight[k] /= wsum;
        added = gather_cache.size() - start;
        gather_from_grid[s] = 1;
      } else {
        gather_cache.resize(start), gather_weight.resize(start);
      }
    }
    if (added == 0) ++surfels_without_gather;
    gather_begin.push_back(std::uint32_t(gather_cache.size()));
  }
  grid_gathered = std::find(gather_from_grid.begin(), gather_from_grid.end(), std::uint8_t(1)) != gather_from_grid.end();
}

void Relighter::Impl::buildInverted() {
  auto invert = [&](const links::LinksView& v, std::vector<std::uint32_t>& begin, std::vector<std::uint32_t>& out) {
    const std::size_t nodes = p.tree.nodeCount();
    begin.assign(nodes + 1, 0);
    for (std::size_t k = 0; k < v.linkCount(); ++k) ++begin[v.node[k] + 1];
    for (std::size_t n = 0; n < nodes; ++n) begin[n + 1] += begin[n];
    out.resize(v.linkCount());
    std::vector<std::uint32_t> fill(begin.begin(), begin.end() - 1);
    for (std::size_t c = 0; c < v.cacheCount(); ++c)
      for (std::uint32_t k = v.offsets[c]; k < v.offsets[c + 1]; ++k) out[fill[v.node[k]]++] = std::uint32_t(c);
  };
  invert(lm_links, lm_inv_begin, lm_inv);
  if (p.has_grid) invert(grid_links, grid_inv_begin, grid_inv);
  inverted_built = true;
}

EffectsPlan Relighter::Impl::makePlan(const LightSet& lights, const RelightOptions& o) const {
  EffectsPlan plan;
  std::size_t emitting = 0;
  for (const auto& e : lights.lights()) emitting += lightEmits(e.light);
  plan.punctual = emitting > 0 || !o.surfel_irradiance.empty();
  plan.reasons.push_back(!o.surfel_irradiance.empty()
                             ? "surfel irradiance given by the caller: surfel direct lighting not evaluated"
                         : plan.punctual ? fmt::format("{} of {} lights emit", emitting, lights.lights().size())
                                         : "no light with non-zero intensity: surfel direct lighting skipped");
  // Emission after overrides: any surfel with non-zero emission?
  std::vector<int> mode(scene.materials.size() + 1, -1);
  std::vector<glm::vec3> value(scene.materials.size() + 1);
  for (const auto& e : lights.emissive())
    if (e.material < int(scene.materials.size()))
      mode[e.material] = int(e.mode), value[e.material] = e.value;
  std::size_t emitters = 0;
  for (std::size_t s = 0; s < p.surfels.size(); ++s) {
    const int m = surfel_material[s];
    glm::vec3 le = p.surfels.emission[s];
    if (m >= 0 && mode[m] == int(EmissiveOverride::Mode::kScale)) le *= value[m];
    if (m >= 0 && mode[m] == int(EmissiveOverride::Mode::kRadiance)) le = value[m];
    emitters += (le.x > 0.0f || le.y > 0.0f || le.z > 0.0f);
  }
  plan.emissive = emitters > 0;
  plan.reasons.push_back(plan.emissive ? fmt::format("{} of {} surfels emit", emitters, p.surfels.size())
                                       : "no emissive surfel: emission term skipped");
  plan.sky = lights.sky().emits();
  plan.reasons.push_back(plan.sky ? "sky emits: sky term added to every cache" : "no sky radiance: sky term skipped");
  plan.grid = p.has_grid && grid_links.cacheCount() > 0;
  plan.reasons.push_back(plan.grid ? fmt::format("{} grid caches", grid_links.cacheCount())
                                   : "no grid caches in the precomputation: grid lighting skipped");
  const bool any = plan.punctual || plan.emissive || plan.sky;
  plan.bounces = o.max_bounces > 0 && any;
  plan.max_bounces = plan.bounces ? o.max_bounces : 0;
  plan.reasons.push_back(!any ? "nothing emits: bounces skipped"
                         : o.max_bounces == 0
                             ? "bounces disabled (max_bounces = 0)"
                             : fmt::format("bounces until one adds < {:g} of the total flux, at most {}",
                                           o.bounce_threshold, o.max_bounces));
  std::size_t baked = 0;
  for (const auto& e : lights.lights()) baked += e.baked && lightEmits(e.light);
  plan.baked_direct = baked > 0;
  plan.reasons.push_back(plan.baked_direct ? fmt::format("{} baked lights: direct light written to {}", baked,
                                                         layer.active() ? fmt::format("the {}x{} direct layer",
                                                                                      layer.width(), layer.height())
                                                                        : std::string("texels"))
                                           : "no baked light: baked direct skipped");
  // Emitter direct needs emitting triangles, not surfels: a lamp smaller than a surfel's
  // footprint still lights its surroundings directly.
  const bool triangles_emit = detail::anyEmitter(scene, lights.emissive());
  plan.emissive_direct = triangles_emit && lights.emissiveBaked();
  plan.reasons.push_back(plan.emissive_direct
                             ? fmt::format("emissive surfaces baked: their direct light sampled into texels ({} "
                                           "samples per texel)",
                                           o.emitter_samples)
                         : !triangles_emit ? "no emitting triangle: emitter direct skipped"
                                           : "emissive_baked = false: emitter direct left to the engine");
  return plan;
}

EffectsPlan Relighter::plan(const LightSet& lights, const RelightOptions& options) const {
  return impl_->makePlan(lights, options);
}

namespace {
// Emitted radiosity per surfel after the overrides (free, so Relighter::surfelEmission can
// compute it without touching the relight state).
void emissionInto(const scene::Scene& scene, const precompute::Precomputation& p,
                  const std::vector<int>& surfel_material, const LightSet& lights,
                  std::vector<glm::vec3>& emission_b) {
  const std::size_t ns = p.surfels.size();
  emission_b.resize(ns);
  std::vector<int> mode(scene.materials.size(), -1);
  std::vector<glm::vec3> value(scene.materials.size());
  for (const auto& e : lights.emissive())
    if (e.material < int(scene.materials.size())) mode[e.material] = int(e.mode), value[e.material] = e.value;
  for (std::size_t s = 0; s < ns; ++s) {
    const int m = surfel_material[s];
    glm::vec3 le = p.surfels.emission[s];
    if (m >= 0 && mode[m] == int(EmissiveOverride::Mode::kScale)) le *= value[m];
    if (m >= 0 && mode[m] == int(EmissiveOverride::Mode::kRadiance)) le = value[m];
    emission_b[s] = kPi * le;  // radiosity of a Lambertian emitter of radiance L: pi L
  }
}
}  // namespace

void Relighter::Impl::computeEmission(const LightSet& lights) {
  emissionInto(scene, p, surfel_material, lights, emission_b);
}

void Relighter::surfelEmission(const LightSet& lights, std::vector<glm::vec3>& out) const {
  emissionInto(impl_->scene, impl_->p, impl_->surfel_material, lights, out);
}

Relighter::GatherTables Relighter::gatherTables() const {
  const Impl& m = *impl_;
  return {m.gather_begin, m.gather_cache, m.gather_weight, m.gather_from_grid, m.lm_has_value, m.grid_has_value,
          m.surfels_without_gather};
}

void Relighter::Impl::lightSurfels(const scene::Light& light, std::vector<glm::vec3>& out,
                                   const std::vector<std::uint32_t>* subset, std::size_t& rays) const {
  // Surfels in tree order are spatial neighbours and every ray ends at the same light (or is
  // parallel to its neighbours): 16-ray packets traverse nearly the same nodes, camera rays
  // reversed. Measured on LightsPunctualLamp (5 point lights, 32k surfels, 2 cores): surfel
  // direct 7.1-9.9 ms as a stream, 6.4-8.5 ms as packets. Lightmap caches jump between
  // charts, so their rays stay on the stream path (packets were slower there).
  shadowedLight(accel, light, p.surfels.position, p.surfels.normal, {}, subset, out, rays, rt::Coherence::kCoherent);
}

void Relighter::Impl::bakedDirect(const scene::Light& light, std::vector<glm::vec3>& out,
                                  const std::vector<std::uint32_t>* subset, std::size_t& rays) const {
  shadowedLight(accel, light, p.lightmap.position, p.lightmap.normal, p.lightmap.valid, subset, out, rays,
                rt::Coherence::kIncoherent);
}

void Relighter::Impl::emitterDirect(const LightSet& lights, int samples, RelightCounts& counts) {
  const detail::EmitterSampler sampler(scene, accel, lights.emissive());
  counts.emitter_triangles = sampler.triangleCount();
  detail::sampleEmitters(sampler, p.lightmap, samples, 0, emitter_cache, counts.shadow_rays);
}

void Relighter::surfelEmitterIrradiance(const LightSet& lights, std::vector<glm::vec3>& out) const {
  const Impl& m = *impl_;
  const std::size_t ns = m.p.surfels.size();
  out.assign(ns, glm::vec3(0.0f));
  if (!detail::anyEmitter(m.scene, lights.emissive())) return;
  const detail::EmitterSampler sampler(m.scene, m.accel, lights.emissive());
  forChunks(ns, kChunk, [&](std::size_t, std::size_t begin, std::size_t end) {
    detail::EmitterSampler::Scratch scratch;
    std::size_t rays = 0;
    for (std::size_t s = begin; s < end; ++s) {
      // Seeded by the surfel, so its noise does not depend on the split; unbiased, and every
      // cache averages many surfels, so 16 samples suffice where a texel's direct needs more.
      const std::uint64_t seed = mixBits(0x73757266656d6974ULL ^ std::uint64_t(s));
      out[s] = sampler.irradiance(m.p.surfels.position[s], m.p.surfels.normal[s], kSurfelEmitterSamples, seed,
                                  scratch, rays);
    }
  });
}

std::size_t Relighter::gridEmitterRadiance(const LightSet& lights, int bands, std::vector<float>& out) const {
  const Impl& m = *impl_;
  out.clear();
  if (!m.p.has_grid || m.p.grid.size() == 0 || !detail::anyEmitter(m.scene, lights.emissive())) return 0;
  const detail::EmitterSampler sampler(m.scene, m.accel, lights.emissive());
  std::size_t rays = 0;
  detail::sampleEmittersSh(sampler, m.p.grid, m.p.grid_fill, bands, kGridEmitterSamples, out, rays);
  return rays;
}

void Relighter::smoothIndirect(RelightResult& res) {
  Impl& m = *impl_;
  const std::size_t stride = std::size_t(3) * res.coeffCount();
  const std::size_t texels = std::size_t(res.width) * res.height;
  if (stride == 0 || res.lightmap_sh.size() != texels * stride || m.texel_map.begin.size() != texels + 1) return;
  if (!m.smooth) m.smooth = detail::IndirectSmooth::build(m.p.lightmap, m.lm_has_value);
  m.smooth->apply(res.lightmap_sh.data(), stride, m.smooth_scratch);
  // Dilated texels average caches whose own texels were just filtered: re-derive them.
  detail::forChunks(texels, 4096, [&](std::size_t, std::size_t begin, std::size_t end) {
    for (std::size_t t = begin; t < end; ++t) {
      const std::uint32_t b0 = m.texel_map.begin[t], b1 = m.texel_map.begin[t + 1];
      if (b0 == b1 || (b1 - b0 == 1 && m.p.lightmap.texel[m.texel_map.point[b0]] == t)) continue;  // own cache
      float* dst = res.lightmap_sh.data() + t * stride;
      std::fill(dst, dst + stride, 0.0f);
      for (std::uint32_t k = b0; k < b1; ++k) {
        const float* src = res.lightmap_sh.data() + std::size_t(m.p.lightmap.texel[m.texel_map.point[k]]) * stride;
        for (std::size_t i = 0; i < stride; ++i) dst[i] += m.texel_map.weight[k] * src[i];
      }
    }
  });
}

void Relighter::Impl::setLeafFlux(std::size_t s) {
  const std::uint32_t leaf = p.tree.leaf_of_surfel[s];
  const glm::vec3 phi = b[s] * pull.surfel[s];
  flux[0][leaf] = phi.x, flux[1][leaf] = phi.y, flux[2][leaf] = phi.z;
}

void Relighter::Impl::pullAll() {
  const auto& t = p.tree;
  // Children have larger indices than their parent: a reverse loop is a bottom-up pull.
  for (std::size_t n = t.nodeCount(); n-- > 0;) {
    if (t.left[n] >= 0)
      for (int ch = 0; ch < 3; ++ch) flux[ch][n] = flux[ch][t.left[n]] + flux[ch][t.right[n]];
    const float inv_area = pull.inv_node[n];
    for (int ch = 0; ch < 3; ++ch) rad_rgbx[4 * n + ch] = flux[ch][n] * inv_area;
  }
}

namespace {
void skyMatrixInto(const Sky& sky, int bands_out, int bands_links, std::vector<float>* sky_matrix) {
  // Truncated SH product: the cache's sky radiance is Lsky(w) * V(w), with V / pi stored per
  // cache as SH (links.sky). M_kj = pi * integral Lsky(w) Y_k(w) Y_j(w) dw, so the sky SH of a
  // cache is M * sky_visibility. Lsky has 3 bands and Y_k Y_j at most 3 + 3, so the integrand
  // is a polynomial of degree <= 8: Gauss-Legendre (8 nodes in cos theta) x 17 equal steps
  // in phi integrate it exactly. A uniform sky gives M = pi * L * identity.
  const int nco = bands_out * bands_out, ncl = bands_links * bands_links;
  const auto lsh = sky.radianceSh();
  std::vector<double> gx, gw;
  gaussLegendre(8, gx, gw);
  constexpr int kPhi = 17;
  for (int ch = 0; ch < 3; ++ch) sky_matrix[ch].assign(std::size_t(nco) * ncl, 0.0f);
  std::vector<double> m[3];
  for (auto& v : m) v.assign(std::size_t(nco) * ncl, 0.0);
  float y[sh::kMaxCoeffs];
  for (int i = 0; i < 8; ++i)
    for (int k = 0; k < kPhi; ++k) {
      const double z = gx[i], r = std::sqrt(std::max(0.0, 1.0 - z * z));
      const double phi = 2.0 * std::numbers::pi * k / kPhi;
      const glm::vec3 w(float(r * std::cos(phi)), float(r * std::sin(phi)), float(z));
      sh::evalBasis(sh::kMaxBands, w, y);
      glm::dvec3 l(0.0);
      for (int c = 0; c < 9; ++c) l += glm::dvec3(lsh[c]) * double(y[c]);
      const double weight = gw[i] * 2.0 * std::numbers::pi / kPhi * std::numbers::pi;
      for (int a = 0; a < nco; ++a)
        for (int b2 = 0; b2 < ncl; ++b2) {
          const double yy = double(y[a]) * y[b2] * weight;
          for (int ch = 0; ch < 3; ++ch) m[ch][std::size_t(a) * ncl + b2] += l[ch] * yy;
        }
    }
  for (int ch = 0; ch < 3; ++ch)
    for (std::size_t i = 0; i < m[ch].size(); ++i) sky_matrix[ch][i] = float(m[ch][i]);
}
}  // namespace

void Relighter::Impl::buildSkyMatrix(const Sky& sky, int bands_out, int bands_links) {
  skyMatrixInto(sky, bands_out, bands_links, sky_matrix);
}

void Relighter::skyMatrix(const Sky& sky, int bands_out, std::vector<float> (&out)[3]) const {
  skyMatrixInto(sky, bands_out, impl_->lm_links.bands, out);
}

void Relighter::Impl::lightCaches(const links::LinksView& view, std::vector<float>& out,
                                  const std::vector<std::uint8_t>& valid, const std::vector<std::uint32_t>* subset,
                                  int bands, LinkForm form, bool sky, const float* rad) {
  const int nc = bands * bands;
  const int ncl = view.bands * view.bands;
  const std::size_t stride = std::size_t(3) * nc;
  out.resize(view.cacheCount() * stride);
  const std::size_t n = subset ? subset->size() : view.cacheCount();
  const detail::NodeRadiance node{rad};
  auto kernel = form == LinkForm::kProjected
                    ? (simd ? detail::lightCacheProjectedAvx2 : detail::lightCacheProjectedScalar)
                    : (simd ? detail::lightCacheRuntimeAvx2 : detail::lightCacheRuntimeScalar);
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, kCacheChunk),
                    [&](const tbb::blocked_range<std::size_t>& r) {
                      for (std::size_t i = r.begin(); i < r.end(); ++i) {
                        const std::size_t c = subset ? (*subset)[i] : i;
                        float* o = out.data() + c * stride;
                        if (!valid[c]) {
                          // Invalid caches get their value from the fill plan.
                          std::fill(o, o + stride, 0.0f);
                          continue;
                        }
                        kernel(view, c, bands, node, o);
                        if (sky) {
                          const float* v = view.sky.data() + c * ncl;
                          for (int ch = 0; ch < 3; ++ch) {
                            const float* m = sky_matrix[ch].data();
                            for (int a = 0; a < nc; ++a) {
                              float s = 0.0f;
                              for (int j = 0; j < ncl; ++j) s += m[a * ncl + j] * v[j];
                              o[ch * nc + a] += s;
                            }
                          }
                        }
                      }
                    });
}

Expected<RelightResult> Relighter::relight(const LightSet& lights, const RelightOptions& o) {
  RelightResult res;
  if (Status s = relightInto(lights, o, res); !s) return s;
  return res;
}

Status validateRequest(const LightSet& lights, const RelightOptions& o, int link_bands, std::size_t surfels,
                       std::size_t materials) {
  const int bands = o.bands == 0 ? link_bands : o.bands;
  if (bands < 1 || bands > sh::kMaxBands) return invalidInput("relight: bands {} not in 1..4", bands);
  if (o.link_form == LinkForm::kProjected && bands > link_bands)
    return invalidInput("relight: bands {} exceeds the {} bands of the projected links (use the runtime form)", bands,
                        link_bands);
  if (o.max_bounces < 0 || o.max_bounces > 1000) return invalidInput("relight: max_bounces {} not in 0..1000", o.max_bounces);
  if (!(o.bounce_threshold >= 0.0f) || !std::isfinite(o.bounce_threshold))
    return invalidInput("relight: bounce_threshold {} must be finite and >= 0", o.bounce_threshold);
  if (o.emitter_samples < 1 || o.emitter_samples > 4096)
    return invalidInput("relight: emitter_samples {} not in 1..4096", o.emitter_samples);
  if (!o.surfel_irradiance.empty() && o.surfel_irradiance.size() != surfels)
    return invalidInput("relight: surfel_irradiance has {} entries for {} surfels", o.surfel_irradiance.size(), surfels);
  if (Status s = lights.checkMaterials(materials); !s) return s;
  for (std::size_t i = 0; i < lights.lights().size(); ++i)
    if (Status s = LightSet::validate(lights.lights()[i], fmt::format("lights[{}]", i)); !s) return s;
  return {};
}

Status Relighter::relightInto(const LightSet& lights, const RelightOptions& o, RelightResult& res) {
  Impl& m = *impl_;
  const int link_bands = m.lm_links.bands;
  const int bands = o.bands == 0 ? link_bands : o.bands;
  if (Status s = validateRequest(lights, o, link_bands, m.p.surfels.size(), m.scene.materials.size()); !s) return s;

  const bool simd_requested = o.kernel == Kernel::kAuto && detail::cpuSupportsAvx2F16c();
  m.simd = simd_requested;
  // Reset everything but the big arrays' capacity (assign() below reuses it: no page
  // faults on the ~100 MB of a 1024^2 lightmap per relight).
  res.timings.clear(), res.bounce_log.clear(), res.warnings.clear();
  res.passes = {}, res.counts = {}, res.bounce_stop.clear(), res.backend = "cpu";
  res.version = lights.version();
  res.kernel = m.simd ? "avx2" : "scalar";
  res.link_form = o.link_form;
  res.bands = bands;
  res.width = m.p.lightmap.width;
  res.height = m.p.lightmap.height;
  res.plan = m.makePlan(lights, o);
  const EffectsPlan& plan = res.plan;
  const std::size_t ns = m.p.surfels.size(), nodes = m.p.tree.nodeCount();
  const int nc = bands * bands;
  const std::size_t stride = std::size_t(3) * nc;
  res.counts.surfels = ns;
  res.counts.nodes = nodes;
  res.counts.caches = m.p.lightmap.size();
  res.counts.grid_caches = plan.grid ? m.grid_links.cacheCount() : 0;
  res.counts.surfels_without_gather = m.surfels_without_gather;
  auto timed = [&](const char* stage, auto&& body) {
    const auto t0 = Clock::now();
    body();
    res.timings.push_back({stage, secondsSince(t0)});
  };

  // ---- incremental eligibility: exactly one light added, removed or changed -----------
  const auto& L = lights.lights();
  int changed = -1;         // index in the new list (added / modified), or in the old (removed)
  enum { kNone, kModified, kAdded, kRemoved } change = kNone;
  const int last_bands = m.last_options.bands ? m.last_options.bands : link_bands;
  bool eligible = o.incremental && o.surfel_irradiance.empty() && m.last_valid && !plan.bounces && !m.last_bounced &&
                  o.link_form == m.last_options.link_form && bands == last_bands && o.kernel == m.last_options.kernel &&
                  lights.sky().radiance == m.last_sky.radiance && lights.sky().sh == m.last_sky.sh &&
                  sameEmissive(lights.emissive(), m.last_emissive) && lights.emissiveBaked() == m.last_emissive_baked &&
                  o.emitter_samples == m.last_options.emitter_samples;
  auto same = [&](std::size_t i, std::size_t j) {
    return L[i].id == m.last_ids[j] && sameLight(L[i].light, m.last_lights[j]) && L[i].baked == bool(m.last_baked[j]);
  };
  // Nothing changed (an editor re-sending the same state, a daemon update that set values
  // to what they were): the kept per-cache state *is* the answer, bounces included, so only
  // the texel pass below runs. Every option that changes the result must match.
  bool unchanged = o.incremental && o.surfel_irradiance.empty() && m.last_valid && o.link_form == m.last_options.link_form && bands == last_bands &&
                   o.kernel == m.last_options.kernel && o.max_bounces == m.last_options.max_bounces &&
                   o.bounce_threshold == m.last_options.bounce_threshold &&
                   o.emitter_samples == m.last_options.emitter_samples && lights.sky().radiance == m.last_sky.radiance &&
                   lights.sky().sh == m.last_sky.sh && sameEmissive(lights.emissive(), m.last_emissive) &&
                   lights.emissiveBaked() == m.last_emissive_baked && L.size() == m.last_ids.size();
  for (std::size_t i = 0; unchanged && i < L.size(); ++i) unchanged = same(i, i);
  if (unchanged) eligible = false;
  if (eligible) {
    const std::size_t nl = L.size(), ol = m.last_ids.size();
    if (nl == ol) {
      int diffs = 0;
      for (std::size_t i = 0; i < nl && diffs <= 1; ++i) {
        if (L[i].id != m.last_ids[i]) diffs = 2;
        else if (!same(i, i)) ++diffs, changed = int(i);
      }
      change = diffs == 1 ? kModified : kNone;
      eligible = diffs == 1;
    } else if (nl == ol + 1) {
      bool prefix = true;
      for (std::size_t i = 0; i < ol; ++i) prefix &= same(i, i);
      eligible = prefix;
      change = kAdded, changed = int(ol);
    } else if (nl + 1 == ol) {
      std::size_t i = 0;
      while (i < nl && same(i, i)) ++i;
      bool rest = true;
      for (std::size_t j = i; j < nl; ++j) rest &= same(j, j + 1);
      eligible = rest;
      change = kRemoved, changed = int(i);
    } else {
      eligible = false;
    }
  }

  if (unchanged) {
    res.passes.unchanged = 1;
    res.bounce_log = m.last_bounce_log;
    res.counts.emitter_triangles = m.emitter_triangles;
  } else if (eligible) {
    // ---- incremental relight --------------------------------------------------------
    res.passes.incremental = 1;
    scene::Light dark;  // stands for "no light": reaches() is false for zero intensity
    dark.intensity = 0.0f;
    const scene::Light& old_light = change == kAdded ? dark : m.last_lights[changed];
    const scene::Light& new_light = change == kRemoved ? dark : L[changed].light;
    const bool old_baked = change != kAdded && m.last_baked[changed];
    const bool new_baked = change != kRemoved && L[changed].baked;
    const bool surfels_change = !sameLight(old_light, new_light);
    std::vector<std::uint32_t> touched;
    timed("surfel_direct", [&] {
      if (!surfels_change) return;
      // In parallel over fixed chunks, concatenated in order: the same list for any thread
      // count. (Made parallel, they took the pass from 3.19 to 2.94 ms, medians of three, when
      // an unranged light reaches all 32k surfels: relight_bench, "incremental (..., range
      // none)", docs/results.md.)
      {
        const std::size_t chunks = (ns + kChunk - 1) / kChunk;
        std::vector<std::vector<std::uint32_t>> part(chunks);
        forChunks(ns, kChunk, [&](std::size_t chunk, std::size_t begin, std::size_t end) {
          for (std::size_t s = begin; s < end; ++s)
            if (reaches(old_light, m.p.surfels.position[s]) || reaches(new_light, m.p.surfels.position[s]))
              part[chunk].push_back(std::uint32_t(s));
        });
        for (const auto& q : part) touched.insert(touched.end(), q.begin(), q.end());
      }
      if (change == kAdded) m.per_light_surfel.emplace_back(ns, glm::vec3(0.0f));
      std::vector<glm::vec3>& contrib = m.per_light_surfel[changed];
      if (change == kRemoved) {
        m.per_light_surfel.erase(m.per_light_surfel.begin() + changed);
      } else {
        std::fill(contrib.begin(), contrib.end(), glm::vec3(0.0f));
        // Every surfel: the full pass, which visits them in the same order and chunks.
        m.lightSurfels(new_light, contrib, touched.size() == ns ? nullptr : &touched, res.counts.shadow_rays);
        res.passes.surfel_direct = 1;
      }
      // Re-sum in light order, exactly as the full relight does (per surfel: any order).
      forChunks(touched.size(), kChunk, [&](std::size_t, std::size_t begin, std::size_t end) {
        for (std::size_t i = begin; i < end; ++i) {
          const std::uint32_t s = touched[i];
          glm::vec3 e(0.0f);
          for (const auto& pl : m.per_light_surfel) e += pl[s];
          if (!m.surfel_emit.empty()) e += m.surfel_emit[s];  // the kept emitter direct
          m.direct_e[s] = e;
          m.b0[s] = m.p.surfels.albedo[s] * e;
          m.b[s] = m.b0[s];
          m.setLeafFlux(s);
        }
      });
      res.counts.surfels_lit = touched.size();
    });
    if (change == kRemoved && !surfels_change) m.per_light_surfel.erase(m.per_light_surfel.begin() + changed);
    if (change == kAdded && !surfels_change) m.per_light_surfel.emplace_back(ns, glm::vec3(0.0f));

    // A change that reaches most surfels (a directional or an unranged point light) changes
    // nearly every node and cache, and the sparse walks below (serial path marking and sort,
    // the inverted link index) then cost more than the full pull and cache lighting: Cornell
    // box medium, all 32k surfels touched, 2 cores: pull 3.2 vs 0.4 ms, cache lighting 6 vs
    // 2.6 ms (the daemon's relight, docs/results.md "Service"). The sums are the same in the
    // same order either way, so the result is identical.
    const bool dense = touched.size() * 2 > ns;
    std::vector<std::uint32_t> changed_nodes;
    timed("pull", [&] {
      if (dense) {
        m.pullAll();
        res.counts.nodes_pulled = nodes;
        res.passes.pulls = 1;
        return;
      }
      if (touched.empty()) return;
      std::vector<std::uint8_t> mark(nodes, 0);
      for (std::uint32_t s : touched) {
        std::int32_t n = std::int32_t(m.p.tree.leaf_of_surfel[s]);
        while (n >= 0 && !mark[n]) mark[n] = 1, changed_nodes.push_back(std::uint32_t(n)), n = m.p.tree.parent[n];
      }
      std::sort(changed_nodes.begin(), changed_nodes.end(), std::greater<>());
      const auto& t = m.p.tree;
      for (std::uint32_t n : changed_nodes) {
        if (t.left[n] >= 0)
          for (int ch = 0; ch < 3; ++ch) m.flux[ch][n] = m.flux[ch][t.left[n]] + m.flux[ch][t.right[n]];
        const float inv_area = m.pull.inv_node[n];
        for (int ch = 0; ch < 3; ++ch) m.rad_rgbx[4 * n + ch] = m.flux[ch][n] * inv_area;
      }
      res.counts.nodes_pulled = changed_nodes.size();
      res.passes.pulls = 1;
    });

    timed("cache_lighting", [&] {
      if (changed_nodes.empty() && !dense) return;
      if (!dense && !m.inverted_built) m.buildInverted();
      auto affected = [&](const std::vector<std::uint32_t>& begin, const std::vector<std::uint32_t>& inv,
                          std::size_t count) {
        std::vector<std::uint8_t> hit(count, 0);
        for (std::uint32_t n : changed_nodes)
          for (std::uint32_t k = begin[n]; k < begin[n + 1]; ++k) hit[inv[k]] = 1;
        std::vector<std::uint32_t> list;
        for (std::size_t c = 0; c < count; ++c)
          if (hit[c]) list.push_back(std::uint32_t(c));
        return list;
      };
      // dense: every cache (a null subset).
      const auto lm_list =
          dense ? std::vector<std::uint32_t>{} : affected(m.lm_inv_begin, m.lm_inv, m.lm_links.cacheCount());
      m.lightCaches(m.lm_links, m.lm_sh, m.p.lightmap.valid, dense ? nullptr : &lm_list, bands, o.link_form, plan.sky,
                    m.rad_rgbx.data());
      res.counts.caches_summed = dense ? m.lm_links.cacheCount() : lm_list.size();
      if (dense) res.counts.links_read += m.lm_links.linkCount();
      for (std::uint32_t c : lm_list) res.counts.links_read += m.lm_links.offsets[c + 1] - m.lm_links.offsets[c];
      res.passes.cache_lighting = 1;
      res.passes.sky = plan.sky ? 1 : 0;
      if (plan.grid) {
        const auto g_list =
            dense ? std::vector<std::uint32_t>{} : affected(m.grid_inv_begin, m.grid_inv, m.grid_links.cacheCount());
        m.lightCaches(m.grid_links, m.grid_sh, m.p.grid.valid, dense ? nullptr : &g_list, bands, o.link_form, plan.sky,
                      m.rad_rgbx.data());
        res.counts.grid_caches_summed = dense ? m.grid_links.cacheCount() : g_list.size();
        res.passes.grid_lighting = 1;
      }
    });

    timed("baked_direct", [&] {
      if (change == kAdded) m.per_light_cache.emplace_back();
      if (change == kRemoved) {
        m.per_light_cache.erase(m.per_light_cache.begin() + changed);
      } else if (new_baked && !m.layer.active()) {
        if (surfels_change || !old_baked || m.per_light_cache[changed].empty()) {
          m.bakedDirect(new_light, m.per_light_cache[changed], nullptr, res.counts.shadow_rays);
          res.passes.baked_direct = 1;
        }
      } else {
        m.per_light_cache[changed].clear();
      }
      std::fill(m.cache_direct.begin(), m.cache_direct.end(), glm::vec3(0.0f));
      for (const auto& pc : m.per_light_cache)
        if (!pc.empty())
          for (std::size_t c = 0; c < m.cache_direct.size(); ++c) m.cache_direct[c] += pc[c];
      // Emission and its sampling are unchanged (eligibility): the kept emitter direct.
      if (!m.emitter_cache.empty())
        for (std::size_t c = 0; c < m.cache_direct.size(); ++c) m.cache_direct[c] += m.emitter_cache[c];
    });
  } else {
    // ---- full relight ---------------------------------------------------------------
    m.direct_e.assign(ns, glm::vec3(0.0f));
    m.per_light_surfel.assign(L.size(), {});
    timed("surfel_direct", [&] {
      if (!o.surfel_irradiance.empty()) {
        // Given by the caller (parity runs): no light is evaluated at the surfels.
        for (auto& pl : m.per_light_surfel) pl.assign(ns, glm::vec3(0.0f));
        m.direct_e.assign(o.surfel_irradiance.begin(), o.surfel_irradiance.end());
        res.counts.surfels_lit = ns;
        return;
      }
      for (std::size_t i = 0; i < L.size(); ++i) {
        if (!lightEmits(L[i].light)) {
          m.per_light_surfel[i].assign(ns, glm::vec3(0.0f));
          continue;
        }
        m.lightSurfels(L[i].light, m.per_light_surfel[i], nullptr, res.counts.shadow_rays);
        res.passes.surfel_direct = 1;
      }
      for (std::size_t i = 0; i < L.size(); ++i)
        for (std::size_t s = 0; s < ns; ++s) m.direct_e[s] += m.per_light_surfel[i][s];
      res.counts.surfels_lit = plan.punctual ? ns : 0;
    });
    timed("emission", [&] {
      if (plan.emissive) {
        m.computeEmission(lights);
        res.passes.emission = 1;
      } else {
        m.emission_b.assign(ns, glm::vec3(0.0f));
      }
    });
    timed("surfel_emitter", [&] {
      // The emitters' direct light at the surfels, sampled (see surfel_emit); it depends only
      // on the emission state, so relights that change punctual lights reuse it.
      if (!m.surfel_emit_valid || !sameEmissive(m.surfel_emit_overrides, lights.emissive())) {
        surfelEmitterIrradiance(lights, m.surfel_emit);
        m.surfel_emit_valid = true;
        m.surfel_emit_overrides = lights.emissive();
        res.passes.surfel_emitter = plan.emissive ? 1 : 0;
      } else if (plan.emissive) {
        res.counts.surfel_emitter_reused = 1;
      }
      for (std::size_t s = 0; s < ns; ++s) m.direct_e[s] += m.surfel_emit[s];
    });
    m.b0.resize(ns);
    for (std::size_t s = 0; s < ns; ++s) m.b0[s] = m.p.surfels.albedo[s] * m.direct_e[s];
    m.b = m.b0;
    if (plan.sky) m.buildSkyMatrix(lights.sky(), bands, link_bands);

    // Grid caches are read by the output and by surfels that gather from the grid. When no
    // surfel does, only the last lighting pass's grid values survive: intermediate passes skip
    // the grid (the same final values, one grid pass per relight instead of one per bounce).
    const bool grid_gathered = m.grid_gathered;
    auto pullAndLight = [&](const char* pull_stage, const char* cache_stage, bool last_pass) {
      timed(pull_stage, [&] {
        for (std::size_t s = 0; s < ns; ++s) m.setLeafFlux(s);
        m.pullAll();
        res.passes.pulls++;
        res.counts.nodes_pulled = nodes;
      });
      timed(cache_stage, [&] {
        m.lightCaches(m.lm_links, m.lm_sh, m.p.lightmap.valid, nullptr, bands, o.link_form, plan.sky,
                      m.rad_rgbx.data());
        res.passes.cache_lighting++;
        res.passes.sky += plan.sky ? 1 : 0;
        res.counts.caches_summed = m.lm_links.cacheCount();
        res.counts.links_read += m.lm_links.linkCount();
        if (plan.grid && (last_pass || grid_gathered)) {
          m.lightCaches(m.grid_links, m.grid_sh, m.p.grid.valid, nullptr, bands, o.link_form, plan.sky,
                        m.rad_rgbx.data());
          res.passes.grid_lighting++;
          res.counts.grid_caches_summed = m.grid_links.cacheCount();
          res.counts.links_read += m.grid_links.linkCount();
        }
      });
    };
    pullAndLight("pull", "cache_lighting", !plan.bounces);
    // The emitters' light reaches the surfels as direct light (surfel_emit, in b0), so the
    // bounces gather reflected light only, like the lightmap caches hold it.

    if (!(plan.punctual || plan.emissive || plan.sky)) res.bounce_stop = "no light";
    else if (o.max_bounces == 0) res.bounce_stop = "disabled";
    else res.bounce_stop = "cap";  // replaced by "threshold" when a bounce adds too little
    if (plan.bounces) {
      std::vector<double> chunk_added, chunk_total;
      for (int k = 1; k <= plan.max_bounces; ++k) {
        const auto t0 = Clock::now();
        // Fill invalid caches first: surfels may gather from them.
        m.applyFill(m.p.lightmap_fill, m.lm_sh.data(), stride);
        if (plan.grid && grid_gathered) m.applyFill(m.p.grid_fill, m.grid_sh.data(), stride);
        const std::size_t chunks = (ns + kChunk - 1) / kChunk;
        chunk_added.assign(chunks, 0.0);
        chunk_total.assign(chunks, 0.0);
        forChunks(ns, kChunk, [&](std::size_t chunk, std::size_t begin, std::size_t end) {
          double added = 0.0, total = 0.0;
          float acc[3 * sh::kMaxCoeffs];
          for (std::size_t s = begin; s < end; ++s) {
            std::fill(acc, acc + stride, 0.0f);
            const bool from_grid = m.gather_from_grid[s];
            const float* base = from_grid ? m.grid_sh.data() : m.lm_sh.data();
            for (std::uint32_t g = m.gather_begin[s]; g < m.gather_begin[s + 1]; ++g) {
              const std::size_t off = std::size_t(m.gather_cache[g]) * stride;
              const float* src = base + off;
              const float wt = m.gather_weight[g];
              for (std::size_t i = 0; i < stride; ++i) acc[i] += wt * src[i];
            }
            const glm::vec3 n = m.p.surfels.normal[s];
            const glm::vec3 e(sh::irradiance(bands, acc, n), sh::irradiance(bands, acc + nc, n),
                              sh::irradiance(bands, acc + 2 * nc, n));
            const glm::vec3 nb = m.b0[s] + m.p.surfels.albedo[s] * e;
            const glm::vec3 d = glm::abs(nb - m.b[s]) * m.p.surfels.area[s];
            added += double(d.x) + d.y + d.z;
            const glm::vec3 phi = (nb + m.emission_b[s]) * m.p.surfels.area[s];
            total += double(phi.x) + phi.y + phi.z;
            m.b[s] = nb;
          }
          chunk_added[chunk] = added;
          chunk_total[chunk] = total;
        });
        double added = 0.0, total = 0.0;  // fixed-order reduction: thread-count independent
        for (std::size_t c = 0; c < chunks; ++c) added += chunk_added[c], total += chunk_total[c];
        res.timings.push_back({fmt::format("bounce{}_gather", k), secondsSince(t0)});
        const bool converged = added < double(o.bounce_threshold) * total;
        pullAndLight(fmt::format("bounce{}_pull", k).c_str(), fmt::format("bounce{}_cache_lighting", k).c_str(),
                     converged || k == plan.max_bounces);
        res.passes.bounces++;
        res.bounce_log.push_back({k, added, total, secondsSince(t0)});
        if (converged) {
          res.bounce_stop = "threshold";
          break;
        }
      }
    }

    timed("baked_direct", [&] {
      m.per_light_cache.assign(L.size(), {});
      m.cache_direct.assign(m.p.lightmap.size(), glm::vec3(0.0f));
      if (!plan.baked_direct || m.layer.active()) return;
      for (std::size_t i = 0; i < L.size(); ++i) {
        if (!L[i].baked || !lightEmits(L[i].light)) continue;
        m.bakedDirect(L[i].light, m.per_light_cache[i], nullptr, res.counts.shadow_rays);
        res.passes.baked_direct++;
      }
      for (const auto& pc : m.per_light_cache)
        if (!pc.empty())
          for (std::size_t c = 0; c < m.cache_direct.size(); ++c) m.cache_direct[c] += pc[c];
    });

    timed("emissive_direct", [&] {
      if (!plan.emissive_direct || m.layer.active()) {
        m.emitter_cache.clear();
        m.emitter_valid = false;
        return;
      }
      if (m.emitter_valid && m.emitter_samples == o.emitter_samples &&
          sameEmissive(m.emitter_overrides, lights.emissive())) {
        res.counts.emitter_direct_reused = 1;
        res.counts.emitter_triangles = m.emitter_triangles;
      } else {
        m.emitterDirect(lights, o.emitter_samples, res.counts);
        m.emitter_valid = true;
        m.emitter_overrides = lights.emissive();
        m.emitter_samples = o.emitter_samples;
        m.emitter_triangles = res.counts.emitter_triangles;
        res.passes.emissive_direct = 1;
      }
      for (std::size_t c = 0; c < m.cache_direct.size(); ++c) m.cache_direct[c] += m.emitter_cache[c];
    });
  }
  m.cache_direct.resize(m.p.lightmap.size(), glm::vec3(0.0f));

  if (plan.grid) {
    timed("grid_emitter", [&] {
      // The emitters' light at the grid caches, sampled; it depends only on the emission
      // state and the bands, so relights that change punctual lights, sky or bounces reuse it.
      if (m.grid_emit_valid && m.grid_emit_bands == bands && sameEmissive(m.grid_emit_overrides, lights.emissive())) {
        res.counts.grid_emitter_reused = m.grid_emit.empty() ? 0 : 1;
        return;
      }
      res.counts.shadow_rays += gridEmitterRadiance(lights, bands, m.grid_emit);
      m.grid_emit_valid = true;
      m.grid_emit_overrides = lights.emissive();
      m.grid_emit_bands = bands;
      res.passes.grid_emitter = m.grid_emit.empty() ? 0 : 1;
    });
  }

  // ---- fill, texels, dilation ------------------------------------------------------------
  timed("fill_dilate", [&] {
    m.applyFill(m.p.lightmap_fill, m.lm_sh.data(), stride);
    m.applyFill(m.p.lightmap_fill, reinterpret_cast<float*>(m.cache_direct.data()), 3);
    if (plan.grid) m.applyFill(m.p.grid_fill, m.grid_sh.data(), stride);
    res.passes.fill = 1;
    const std::size_t texels = std::size_t(res.width) * res.height;
    // Every texel is written below (value or zero), so resize() need not clear.
    res.lightmap_sh.resize(texels * stride);
    const bool coarse_direct = !m.layer.active();
    if (coarse_direct) {
      res.direct.resize(texels);
      res.direct_width = res.width, res.direct_height = res.height;
      res.direct_valid.clear();
    }
    res.texel_valid.resize(texels);
    forChunks(texels, 4096, [&](std::size_t, std::size_t begin, std::size_t end) {
      for (std::size_t t = begin; t < end; ++t) {
        float* dst = res.lightmap_sh.data() + t * stride;
        const std::uint32_t b0 = m.texel_map.begin[t], b1 = m.texel_map.begin[t + 1];
        if (b0 == b1) {
          std::fill(dst, dst + stride, 0.0f);
          if (coarse_direct) res.direct[t] = glm::vec3(0.0f);
          res.texel_valid[t] = 0;
          continue;
        }
        if (b1 - b0 == 1 && m.texel_map.weight[b0] == 1.0f) {  // a texel with its own cache
          const std::uint32_t c = m.texel_map.point[b0];
          std::memcpy(dst, m.lm_sh.data() + std::size_t(c) * stride, stride * sizeof(float));
          if (coarse_direct) res.direct[t] = m.cache_direct[c];
          res.texel_valid[t] = 1;
          continue;
        }
        std::fill(dst, dst + stride, 0.0f);
        glm::vec3 dir(0.0f);
        for (std::uint32_t k = b0; k < b1; ++k) {
          const std::uint32_t c = m.texel_map.point[k];
          const float w = m.texel_map.weight[k];
          const float* src = m.lm_sh.data() + std::size_t(c) * stride;
          for (std::size_t i = 0; i < stride; ++i) dst[i] += w * src[i];
          dir += w * m.cache_direct[c];
        }
        if (coarse_direct) res.direct[t] = dir;
        res.texel_valid[t] = 1;
      }
    });
    res.counts.texels = texels;
    res.counts.texels_filled = std::size_t(std::count(res.texel_valid.begin(), res.texel_valid.end(), 1));
    res.seams = {}, res.direct_seams = {};
    if (o.smooth_indirect) smoothIndirect(res);
    if (o.stitch_seams) {
      m.seams.apply(res.lightmap_sh.data(), stride, &res.seams);
      if (coarse_direct) m.seams.apply(reinterpret_cast<float*>(res.direct.data()), 3, &res.direct_seams);
    }
    if (plan.grid) {
      // Links' reflected light and sky, plus the emitters' sampled light (both filled).
      res.grid_sh = m.grid_sh;
      if (!m.grid_emit.empty())
        for (std::size_t i = 0; i < res.grid_sh.size(); ++i) res.grid_sh[i] += m.grid_emit[i];
    }
    res.surfel_radiosity.resize(ns);
    for (std::size_t s = 0; s < ns; ++s) res.surfel_radiosity[s] = m.b[s] + m.emission_b[s];
  });
  if (m.layer.active()) m.layer.compute(lights, o, plan, res);
  if (res.passes.incremental) res.bounce_stop = "disabled";
  if (res.passes.unchanged) res.bounce_stop = m.last_bounce_stop;
  m.last_bounce_log = res.bounce_log;
  m.last_bounce_stop = res.bounce_stop;

  // Remember what was computed, for the next incremental relight.
  m.last_lights.clear(), m.last_ids.clear(), m.last_baked.clear();
  for (const auto& e : L) m.last_lights.push_back(e.light), m.last_ids.push_back(e.id), m.last_baked.push_back(e.baked);
  m.last_emissive = lights.emissive();
  m.last_emissive_baked = lights.emissiveBaked();
  m.last_sky = lights.sky();
  m.last_options = o;
  m.last_bounced = plan.bounces;
  m.last_valid = o.surfel_irradiance.empty();  // a given irradiance is not a light state to build on
  if (m.surfels_without_gather > 0 && plan.bounces)
    res.warnings.push_back(fmt::format("{} surfels have no lightmap texel or grid cache to gather bounces from",
                                       m.surfels_without_gather));
  return {};
}

}  // namespace lightlink::relight
