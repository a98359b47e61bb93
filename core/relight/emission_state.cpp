#include "core/relight/emission_state.h"

#include <numbers>

#include "core/common/sampling.h"
#include "core/relight/direct_points.h"

namespace lightlink::relight {

using detail::forChunks;
using detail::kChunk;

void surfelEmissionInto(const SceneTables& t, const LightSet& lights, std::vector<glm::vec3>& out) {
  const auto& p = t.p;
  const std::size_t ns = p.surfels.size(), materials = t.scene.materials.size();
  out.resize(ns);
  std::vector<int> mode(materials, -1);
  std::vector<glm::vec3> value(materials);
  for (const auto& e : lights.emissive())
    if (e.material < int(materials)) mode[e.material] = int(e.mode), value[e.material] = e.value;
  for (std::size_t s = 0; s < ns; ++s) {
    const int m = t.surfel_material[s];
    glm::vec3 le = p.surfels.emission[s];
    if (m >= 0 && mode[m] == int(EmissiveOverride::Mode::kScale)) le *= value[m];
    if (m >= 0 && mode[m] == int(EmissiveOverride::Mode::kRadiance)) le = value[m];
    out[s] = std::numbers::pi_v<float> * le;  // radiosity of a Lambertian emitter of radiance L: pi L
  }
}

bool EmissionState::updateEmission(const LightSet& lights) {
  if (emission_valid_ && detail::sameEmissive(emission_overrides_, lights.emissive())) return false;
  surfelEmissionInto(t_, lights, emission_);
  emission_overrides_ = lights.emissive();
  emission_valid_ = true;
  ++emission_generation_;
  return true;
}

namespace {

// Each point's rotation of the sample pattern, from its seed.
template <class Seed>
std::vector<glm::vec2> rotations(std::size_t n, Seed&& seed) {
  std::vector<glm::vec2> r(n);
  for (std::size_t i = 0; i < n; ++i) r[i] = detail::emitterRotation(seed(i));
  return r;
}

}  // namespace

EmitterUpdate EmissionState::updateSurfels(const LightSet& lights) {
  const auto& surfels = t_.p.surfels;
  return surfel_.update(t_.scene, t_.accel, lights.emissive(), kSurfelEmitterSamples, surfels.size(), 3,
                        [&](const detail::EmitterSampler& sampler, std::vector<float>& layers) {
    if (sampler.triangleCount() == 0) return;
    if (tracer_) {
      const auto rot = rotations(surfels.size(), [](std::size_t s) { return detail::surfelEmitterSeed(s); });
      std::size_t uncounted = 0;  // as on the host, the surfels' rays are not counted
      if (detail::traceEmitters(tracer_, sampler, {surfels.position, surfels.normal, {}, rot}, kSurfelEmitterSamples, 0,
                                "surfel_emitter", layers, uncounted, *log_))
        return;
    }
    const std::size_t L = std::size_t(sampler.layerCount());
    forChunks(surfels.size(), kChunk, [&](std::size_t, std::size_t begin, std::size_t end) {
      detail::EmitterSampler::Scratch scratch;
      std::size_t r = 0;
      for (std::size_t s = begin; s < end; ++s) {
        // Seeded by the surfel, so its noise does not depend on the split; unbiased, and every
        // cache averages many surfels, so 16 samples suffice where a texel's direct needs more.
        const std::uint64_t seed = detail::surfelEmitterSeed(s);
        sampler.irradiance(surfels.position[s], surfels.normal[s], kSurfelEmitterSamples, seed, scratch,
                           reinterpret_cast<glm::vec3*>(layers.data() + s * L * 3), r);
      }
    });
  });
}

EmitterUpdate EmissionState::updateTexels(const LightSet& lights, int samples, std::size_t& rays) {
  const auto how = texel_.update(t_.scene, t_.accel, lights.emissive(), samples, t_.p.lightmap.size(), 3,
                                 [&](const detail::EmitterSampler& sampler, std::vector<float>& layers) {
    const auto& lm = t_.p.lightmap;
    if (tracer_ && sampler.triangleCount() > 0) {
      const auto rot = rotations(lm.size(), [&](std::size_t c) { return detail::texelEmitterSeed(lm.texel[c], 0); });
      if (detail::traceEmitters(tracer_, sampler, {lm.position, lm.normal, lm.valid, rot}, samples, 0,
                                "emissive_direct", layers, rays, *log_))
        return;
    }
    detail::sampleEmitters(sampler, lm, samples, 0, layers, rays);
  });
  if (how != EmitterUpdate::kKept) ++texel_generation_;
  return how;
}

void EmissionState::dropTexels() {
  if (!texel_.valid()) return;
  texel_.clear();
  ++texel_generation_;
}

EmitterUpdate EmissionState::updateGrid(const LightSet& lights, int bands, std::size_t& rays) {
  const auto& p = t_.p;
  if (!p.has_grid || p.grid.size() == 0) {
    const bool had = grid_light_.valid();
    grid_light_.clear(), grid_.clear();
    return had ? EmitterUpdate::kSampled : EmitterUpdate::kKept;
  }
  const std::size_t stride = std::size_t(3) * bands * bands;
  const auto how = grid_light_.update(t_.scene, t_.accel, lights.emissive(), bands, p.grid.size(), stride,
                                      [&](const detail::EmitterSampler& sampler, std::vector<float>& layers) {
    if (sampler.triangleCount() == 0) return;
    if (tracer_) {
      const auto rot = rotations(p.grid.size(), [](std::size_t c) { return detail::gridEmitterSeed(c); });
      if (detail::traceEmitters(tracer_, sampler, {p.grid.position, {}, p.grid.valid, rot}, kGridEmitterSamples, bands,
                                "grid_emitter", layers, rays, *log_))
        return;
    }
    detail::sampleEmittersSh(sampler, p.grid, bands, kGridEmitterSamples, layers, rays);
  });
  if (how == EmitterUpdate::kKept) return how;
  if (grid_light_.triangles() == 0) {
    grid_.clear();
    return how;
  }
  const auto v = grid_light_.value();
  grid_.assign(v.begin(), v.end());
  detail::applyFill(p.grid_fill, grid_.data(), stride);  // as the caches' own SH gets it
  return how;
}

void EmissionState::invalidate() {
  emission_valid_ = false;
  surfel_.clear(), texel_.clear(), grid_light_.clear();
}

}  // namespace lightlink::relight
