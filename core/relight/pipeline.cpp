#include "core/relight/pipeline.h"

#include <chrono>
#include <cmath>
#include <numbers>

#include "core/relight/direct_points.h"
#include "core/relight/emitter_direct.h"
#include "core/sh/sh.h"

namespace lightlink::relight {
namespace {

using detail::lightEmits;
using detail::sameEmissive;
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
  if (o.surfel_shadow_rays < 1 || o.surfel_shadow_rays > 64)
    return invalidInput("relight: surfel_shadow_rays {} not in 1..64", o.surfel_shadow_rays);
  if (o.emitter_samples < 1 || o.emitter_samples > 4096)
    return invalidInput("relight: emitter_samples {} not in 1..4096", o.emitter_samples);
  if (!o.surfel_irradiance.empty() && o.surfel_irradiance.size() != surfels)
    return invalidInput("relight: surfel_irradiance has {} entries for {} surfels", o.surfel_irradiance.size(), surfels);
  if (Status s = lights.checkMaterials(materials); !s) return s;
  for (std::size_t i = 0; i < lights.lights().size(); ++i)
    if (Status s = LightSet::validate(lights.lights()[i], fmt::format("lights[{}]", i)); !s) return s;
  return {};
}

EffectsPlan RelightPipeline::plan(const LightSet& lights, const RelightOptions& o) const {
  const auto& p = t_.p;
  const auto& scene = t_.scene;
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
    const int m = t_.surfel_material[s];
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
  plan.grid = p.has_grid && t_.grid_links.cacheCount() > 0;
  plan.reasons.push_back(plan.grid ? fmt::format("{} grid caches", t_.grid_links.cacheCount())
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
                                                         layer_.active() ? fmt::format("the {}x{} direct layer",
                                                                                      layer_.width(), layer_.height())
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

void RelightPipeline::smoothIndirect(RelightResult& res) {
  const std::size_t stride = std::size_t(3) * res.coeffCount();
  const std::size_t texels = std::size_t(res.width) * res.height;
  if (stride == 0 || res.lightmap_sh.size() != texels * stride || t_.texel_map.begin.size() != texels + 1) return;
  if (!smooth_) smooth_ = detail::IndirectSmooth::build(t_.p.lightmap, t_.lm_has_value);
  smooth_->apply(res.lightmap_sh.data(), stride, smooth_scratch_);
  // Dilated texels average caches whose own texels were just filtered: re-derive them.
  detail::forChunks(texels, 4096, [&](std::size_t, std::size_t begin, std::size_t end) {
    for (std::size_t t = begin; t < end; ++t) {
      const std::uint32_t b0 = t_.texel_map.begin[t], b1 = t_.texel_map.begin[t + 1];
      if (b0 == b1 || (b1 - b0 == 1 && t_.p.lightmap.texel[t_.texel_map.point[b0]] == t)) continue;  // own cache
      float* dst = res.lightmap_sh.data() + t * stride;
      std::fill(dst, dst + stride, 0.0f);
      for (std::uint32_t k = b0; k < b1; ++k) {
        const float* src = res.lightmap_sh.data() + std::size_t(t_.p.lightmap.texel[t_.texel_map.point[k]]) * stride;
        for (std::size_t i = 0; i < stride; ++i) dst[i] += t_.texel_map.weight[k] * src[i];
      }
    }
  });
}

RelightPipeline::RelightPipeline(const SceneTables& tables, std::unique_ptr<RelightPasses> passes)
    : t_(tables),
      passes_(std::move(passes)),
      emission_(tables),
      layer_(tables.scene, tables.accel, tables.p),
      seams_(SeamStitch::build(tables.scene, tables.p.lightmap.width, tables.p.lightmap.height)) {
  emission_.setTracer(passes_->emitterTracer(), &trace_log_);
  layer_.setTracer(passes_->emitterTracer(), &trace_log_);
}

RelightPipeline::~RelightPipeline() = default;

void RelightPipeline::invalidate(bool everything) {
  memo_.valid = false;
  layer_.invalidate(everything);
  if (everything) emission_.invalidate();
}

void RelightPipeline::resetResult(const LightSet& lights, const RelightOptions& o, int bands,
                                  RelightResult& res) const {
  // Reset everything but the big arrays' capacity (the passes reuse it: no page faults on
  // the ~100 MB of a 1024^2 lightmap per relight).
  res.timings.clear(), res.bounce_log.clear(), res.warnings.clear();
  res.passes = {}, res.counts = {}, res.bounce_stop.clear();
  res.backend = std::string(passes_->backend());
  res.kernel = passes_->kernelName(o);
  res.version = lights.version();
  res.link_form = o.link_form;
  res.bands = bands;
  res.width = t_.p.lightmap.width;
  res.height = t_.p.lightmap.height;
  res.plan = plan(lights, o);
  res.counts.surfels = t_.surfelCount();
  res.counts.nodes = t_.nodeCount();
  res.counts.caches = t_.p.lightmap.size();
  res.counts.grid_caches = res.plan.grid ? t_.grid_links.cacheCount() : 0;
  res.counts.surfels_without_gather = t_.surfels_without_gather;
}

Status RelightPipeline::relightInto(const LightSet& lights, const RelightOptions& o, RelightResult& res) {
  const int link_bands = t_.lm_links.bands;
  const int bands = o.bands == 0 ? link_bands : o.bands;
  if (Status s = validateRequest(lights, o, link_bands, t_.surfelCount(), t_.scene.materials.size()); !s) return s;
  resetResult(lights, o, bands, res);
  trace_log_.clear();
  // Until this relight completes, the kept state is no base for a shortcut.
  const Memo* memo = memo_.valid ? &memo_ : nullptr;
  const bool warm = o.warm_start && memo && res.plan.bounces && warmBase(o, bands);
  const RelightFrame f{lights, o, res.plan, bands, std::size_t(3) * bands * bands, !layer_.active(), sky_matrix_,
                       warm};
  Status st = passes_->begin(f);
  // A warm relight of an unchanged light set is one more iteration towards convergence.
  if (st && memo && !warm && unchanged(lights, o, bands)) {
    // The kept per-cache state *is* the answer, bounces included: only the texels are written.
    res.passes.unchanged = 1;
    res.bounce_log = memo_.bounce_log;
    res.counts.emitter_triangles = emission_.emitterTriangles();
  } else if (st) {
    const auto change = memo && passes_->incremental() ? oneChange(lights, o, res.plan, bands) : std::nullopt;
    memo_.valid = false;
    if (change) {
      res.passes.incremental = 1;
      st = passes_->relightChange(f, *change, emission_.surfels(), emission_.texels(), res);
      if (st && res.plan.bounces) st = changeLoop(f, res);
    } else {
      st = fullRelight(f, res);
    }
  }
  if (st && res.plan.grid) gridEmitter(f, res);
  if (st) st = passes_->texels(f, res);
  if (!st) {
    memo_.valid = false;
    return st;
  }
  finish(f, res);
  remember(f, res);
  return {};
}

bool RelightPipeline::incrementalFor(const LightSet& lights, const RelightOptions& o) const {
  if (!memo_.valid || !passes_->incremental()) return false;
  const int bands = o.bands == 0 ? t_.lm_links.bands : o.bands;
  if (!validateRequest(lights, o, t_.lm_links.bands, t_.surfelCount(), t_.scene.materials.size())) return false;
  return !unchanged(lights, o, bands) && oneChange(lights, o, plan(lights, o), bands).has_value();
}

bool RelightPipeline::warmBase(const RelightOptions& o, int bands) const {
  const Memo& m = memo_;
  const int last_bands = m.options.bands ? m.options.bands : t_.lm_links.bands;
  return o.surfel_irradiance.empty() && o.link_form == m.options.link_form && bands == last_bands &&
         o.kernel == m.options.kernel;
}

bool RelightPipeline::sameSetting(const LightSet& lights, const RelightOptions& o, int bands) const {
  const Memo& m = memo_;
  const int last_bands = m.options.bands ? m.options.bands : t_.lm_links.bands;
  return o.incremental && o.surfel_irradiance.empty() && o.link_form == m.options.link_form &&
         bands == last_bands && o.kernel == m.options.kernel && o.emitter_samples == m.options.emitter_samples &&
         o.surfel_shadow_rays == m.options.surfel_shadow_rays &&
         lights.sky().radiance == m.sky.radiance && lights.sky().sh == m.sky.sh &&
         sameEmissive(lights.emissive(), m.emissive) && lights.emissiveBaked() == m.emissive_baked;
}

bool RelightPipeline::sameEntry(const LightEntry& e, std::size_t j) const {
  return e.id == memo_.ids[j] && sameLight(e.light, memo_.lights[j]) && e.baked == bool(memo_.baked[j]);
}

bool RelightPipeline::unchanged(const LightSet& lights, const RelightOptions& o, int bands) const {
  // Every option that changes the result must match, the bounce options included.
  const auto& L = lights.lights();
  // A warm relight's answer depends on the one before it: no base for "unchanged".
  if (memo_.warm || !sameSetting(lights, o, bands) || o.max_bounces != memo_.options.max_bounces ||
      o.bounce_threshold != memo_.options.bounce_threshold || L.size() != memo_.ids.size())
    return false;
  for (std::size_t i = 0; i < L.size(); ++i)
    if (!sameEntry(L[i], i)) return false;
  return true;
}

std::optional<LightChange> RelightPipeline::oneChange(const LightSet& lights, const RelightOptions& o,
                                                      const EffectsPlan& plan, int bands) const {
  const Memo& m = memo_;
  if (!sameSetting(lights, o, bands) || plan.bounces != m.bounced) return std::nullopt;
  // With bounces, the change is propagated on top of the last solution: it must be one
  // converged to the same threshold (a warm relight's included; the cap may differ).
  if (plan.bounces && (!passes_->incrementalBounces() || m.bounce_stop != "threshold" ||
                       o.bounce_threshold != m.options.bounce_threshold))
    return std::nullopt;
  const auto& L = lights.lights();
  auto same = [&](std::size_t i, std::size_t j) { return sameEntry(L[i], j); };
  scene::Light dark;  // stands for "no light": reaches() is false for zero intensity
  dark.intensity = 0.0f;
  LightChange c;
  const std::size_t nl = L.size(), ol = m.ids.size();
  if (nl == ol) {
    int diffs = 0;
    for (std::size_t i = 0; i < nl && diffs <= 1; ++i) {
      if (L[i].id != m.ids[i]) diffs = 2;
      else if (!same(i, i)) ++diffs, c.index = i;
    }
    if (diffs != 1) return std::nullopt;
    c.kind = LightChange::Kind::kModified;
  } else if (nl == ol + 1) {
    for (std::size_t i = 0; i < ol; ++i)
      if (!same(i, i)) return std::nullopt;
    c.kind = LightChange::Kind::kAdded, c.index = ol;
  } else if (nl + 1 == ol) {
    std::size_t i = 0;
    while (i < nl && same(i, i)) ++i;
    for (std::size_t j = i; j < nl; ++j)
      if (!same(j, j + 1)) return std::nullopt;
    c.kind = LightChange::Kind::kRemoved, c.index = i;
  } else {
    return std::nullopt;
  }
  const bool added = c.kind == LightChange::Kind::kAdded, removed = c.kind == LightChange::Kind::kRemoved;
  c.old_light = added ? dark : m.lights[c.index];
  c.new_light = removed ? dark : L[c.index].light;
  c.old_baked = !added && m.baked[c.index];
  c.new_baked = !removed && L[c.index].baked;
  return c;
}

Status RelightPipeline::fullRelight(const RelightFrame& f, RelightResult& res) {
  const EffectsPlan& plan = f.plan;
  timedStage(res, "emission", [&] {
    emission_.updateEmission(f.lights);
    res.passes.emission = plan.emissive ? 1 : 0;
  });
  if (Status s = passes_->setEmission(emission_.emission(), emission_.emissionGeneration()); !s) return s;
  timedStage(res, "surfel_emitter", [&] {
    // The emitters' direct light at the surfels, sampled; it depends only on the emission
    // state, so relights that change punctual lights reuse it.
    const EmitterUpdate how = emission_.updateSurfels(f.lights);
    if (how == EmitterUpdate::kSampled) res.passes.surfel_emitter = plan.emissive ? 1 : 0;
    else if (plan.emissive) res.counts.surfel_emitter_reused = 1;
    if (how == EmitterUpdate::kRescaled) res.counts.emitter_rescaled++;
  });
  if (plan.sky) skyMatrixInto(f.lights.sky(), f.bands, t_.lm_links.bands, sky_matrix_);
  if (Status s = passes_->surfelDirect(f, emission_.surfels(), res); !s) return s;
  // Grid caches are read by the output and by surfels that gather from the grid. When no
  // surfel does, only the last lighting pass's grid values survive: intermediate passes skip
  // the grid (the same final values, one grid pass per relight instead of one per bounce).
  // Warm, the first gather reads the last relight's caches instead of freshly lit ones.
  res.passes.warm = f.warm ? 1 : 0;
  if (!f.warm)
    if (Status s = passes_->pullAndLight(f, "", plan.grid && (!plan.bounces || t_.grid_gathered), res); !s) return s;
  if (!(plan.punctual || plan.emissive || plan.sky)) res.bounce_stop = "no light";
  else if (f.options.max_bounces == 0) res.bounce_stop = "disabled";
  else res.bounce_stop = "cap";  // replaced by "threshold" when a bounce adds too little
  if (plan.bounces)
    if (Status s = bounceLoop(f, res); !s) return s;
  emitterTexels(f, res);
  return passes_->cacheDirect(f, emission_.texels(), res);
}

Status RelightPipeline::bounceLoop(const RelightFrame& f, RelightResult& res) {
  // The emitters' light reached the surfels as direct light (EmissionState::surfels), so the
  // bounces gather reflected light only, as the lightmap caches hold it.
  const EffectsPlan& plan = f.plan;
  const double threshold = double(f.options.bounce_threshold);
  for (int k = 1; k <= plan.max_bounces; ++k) {
    const auto t0 = Clock::now();
    if (Status s = passes_->gather(f, k, plan.grid && t_.grid_gathered, res); !s) return s;
    res.counts.surfels_gathered += t_.surfelCount();
    std::optional<BounceSums> sums;
    if (!passes_->sumsLag()) {
      auto got = passes_->bounceSums();
      if (!got) return got.status();
      sums = *got;
    }
    // Without the sums yet, this pass may be the last: the grid is lit in case.
    const bool maybe_last = k == plan.max_bounces || !sums || sums->added < threshold * sums->total;
    if (Status s = passes_->pullAndLight(f, fmt::format("bounce{}_", k), plan.grid && (t_.grid_gathered || maybe_last),
                                         res);
        !s)
      return s;
    if (!sums) {
      auto got = passes_->bounceSums();
      if (!got) return got.status();
      sums = *got;
    }
    res.passes.bounces++;
    res.bounce_log.push_back({k, sums->added, sums->total, secondsSince(t0)});
    if (sums->added < threshold * sums->total) {
      res.bounce_stop = "threshold";
      break;
    }
  }
  return {};
}

Status RelightPipeline::changeLoop(const RelightFrame& f, RelightResult& res) {
  // The same stop rule as the bounce loop's, on the flux each round of the change moves.
  const double threshold = double(f.options.bounce_threshold);
  res.bounce_stop = "cap";
  for (int k = 1; k <= f.plan.max_bounces; ++k) {
    const auto t0 = Clock::now();
    auto sums = passes_->propagateChange(f, k, res);
    if (!sums) return sums.status();
    res.passes.bounces++;
    res.bounce_log.push_back({k, sums->added, sums->total, secondsSince(t0)});
    if (sums->added == 0.0 || sums->added < threshold * sums->total) {
      res.bounce_stop = "threshold";
      break;
    }
  }
  return {};
}

void RelightPipeline::emitterTexels(const RelightFrame& f, RelightResult& res) {
  timedStage(res, "emissive_direct", [&] {
    // A finer direct layer samples the emitters itself.
    if (!f.plan.emissive_direct || !f.coarse_direct) {
      emission_.dropTexels();
      return;
    }
    const EmitterUpdate how = emission_.updateTexels(f.lights, f.options.emitter_samples, res.counts.shadow_rays);
    if (how == EmitterUpdate::kSampled) res.passes.emissive_direct = 1;
    else res.counts.emitter_direct_reused = 1;
    if (how == EmitterUpdate::kRescaled) res.counts.emitter_rescaled++;
    res.counts.emitter_triangles = emission_.emitterTriangles();
  });
}

void RelightPipeline::gridEmitter(const RelightFrame& f, RelightResult& res) {
  timedStage(res, "grid_emitter", [&] {
    // The emitters' light at the grid caches, sampled; it depends only on the emission
    // state and the bands, so relights that change punctual lights, sky or bounces reuse it.
    const EmitterUpdate how = emission_.updateGrid(f.lights, f.bands, res.counts.shadow_rays);
    const int has = emission_.grid().empty() ? 0 : 1;
    if (how == EmitterUpdate::kSampled) res.passes.grid_emitter = has;
    else res.counts.grid_emitter_reused = std::size_t(has);
    if (how == EmitterUpdate::kRescaled && has) res.counts.emitter_rescaled++;
  });
}

void RelightPipeline::finish(const RelightFrame& f, RelightResult& res) {
  const RelightOptions& o = f.options;
  timedStage(res, "texel_filters", [&] {
    // Links' reflected light and sky, plus the emitters' sampled light (both filled).
    const auto& grid_emit = emission_.grid();
    if (f.plan.grid && grid_emit.size() == res.grid_sh.size())
      for (std::size_t i = 0; i < res.grid_sh.size(); ++i) res.grid_sh[i] += grid_emit[i];
    const auto emission = emission_.emission();
    if (emission.size() == res.surfel_radiosity.size())
      for (std::size_t s = 0; s < emission.size(); ++s) res.surfel_radiosity[s] += emission[s];
    res.seams = {}, res.direct_seams = {};
    if (o.smooth_indirect) smoothIndirect(res);
    if (o.stitch_seams) {
      seams_.apply(res.lightmap_sh.data(), f.stride, &res.seams);
      if (f.coarse_direct) seams_.apply(reinterpret_cast<float*>(res.direct.data()), 3, &res.direct_seams);
    }
  });
  if (layer_.active()) layer_.compute(f.lights, o, f.plan, res);
  // The backend's emitter sampling: its device time per stage, and where it left the host to
  // sample (with why).
  for (auto& t : trace_log_.timings) res.timings.push_back(std::move(t));
  for (auto& note : trace_log_.notes) res.plan.reasons.push_back(std::move(note));
  trace_log_.clear();
  if (res.passes.incremental && !f.plan.bounces) res.bounce_stop = "disabled";
  if (res.passes.unchanged) res.bounce_stop = memo_.bounce_stop;
  if (t_.surfels_without_gather > 0 && f.plan.bounces)
    res.warnings.push_back(fmt::format("{} surfels have no lightmap texel or grid cache to gather bounces from",
                                       t_.surfels_without_gather));
}

void RelightPipeline::remember(const RelightFrame& f, const RelightResult& res) {
  Memo& m = memo_;
  m.lights.clear(), m.ids.clear(), m.baked.clear();
  for (const auto& e : f.lights.lights()) m.lights.push_back(e.light), m.ids.push_back(e.id), m.baked.push_back(e.baked);
  m.emissive = f.lights.emissive();
  m.emissive_baked = f.lights.emissiveBaked();
  m.sky = f.lights.sky();
  m.options = f.options;
  m.options.surfel_irradiance = {};  // a view into the caller's memory: not kept
  m.bounced = f.plan.bounces;
  m.warm = f.warm;
  m.bounce_log = res.bounce_log;
  m.bounce_stop = res.bounce_stop;
  m.valid = f.options.surfel_irradiance.empty();  // a given irradiance is not a light state to build on
}
}  // namespace lightlink::relight
