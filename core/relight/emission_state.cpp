#include "core/relight/emission_state.h"

#include <numbers>

#include "core/common/sampling.h"
#include "core/relight/direct_points.h"
#include "core/relight/emitter_direct.h"

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

bool EmissionState::Key::matches(const LightSet& lights, int c) const {
  return valid && count == c && detail::sameEmissive(overrides, lights.emissive());
}

void EmissionState::Key::set(const LightSet& lights, int c) {
  valid = true, overrides = lights.emissive(), count = c;
}

bool EmissionState::updateEmission(const LightSet& lights) {
  if (emission_key_.matches(lights, 0)) return false;
  surfelEmissionInto(t_, lights, emission_);
  emission_key_.set(lights, 0);
  ++emission_generation_;
  return true;
}

bool EmissionState::updateSurfels(const LightSet& lights) {
  if (surfel_key_.matches(lights, kSurfelEmitterSamples)) return false;
  const std::size_t ns = t_.p.surfels.size();
  surfel_.assign(ns, glm::vec3(0.0f));
  surfel_key_.set(lights, kSurfelEmitterSamples);
  if (!detail::anyEmitter(t_.scene, lights.emissive())) return true;
  const detail::EmitterSampler sampler(t_.scene, t_.accel, lights.emissive());
  forChunks(ns, kChunk, [&](std::size_t, std::size_t begin, std::size_t end) {
    detail::EmitterSampler::Scratch scratch;
    std::size_t r = 0;
    for (std::size_t s = begin; s < end; ++s) {
      // Seeded by the surfel, so its noise does not depend on the split; unbiased, and every
      // cache averages many surfels, so 16 samples suffice where a texel's direct needs more.
      const std::uint64_t seed = mixBits(0x73757266656d6974ULL ^ std::uint64_t(s));
      surfel_[s] = sampler.irradiance(t_.p.surfels.position[s], t_.p.surfels.normal[s], kSurfelEmitterSamples, seed,
                                      scratch, r);
    }
  });
  return true;
}

bool EmissionState::updateTexels(const LightSet& lights, int samples, std::size_t& rays) {
  if (texel_key_.matches(lights, samples)) return false;
  const detail::EmitterSampler sampler(t_.scene, t_.accel, lights.emissive());
  triangles_ = sampler.triangleCount();
  detail::sampleEmitters(sampler, t_.p.lightmap, samples, 0, texel_, rays);
  texel_key_.set(lights, samples);
  ++texel_generation_;
  return true;
}

void EmissionState::dropTexels() {
  if (texel_.empty() && !texel_key_.valid) return;
  texel_.clear();
  texel_key_.valid = false;
  ++texel_generation_;
}

bool EmissionState::updateGrid(const LightSet& lights, int bands, std::size_t& rays) {
  if (grid_key_.matches(lights, bands)) return false;
  grid_.clear();
  grid_key_.set(lights, bands);
  const auto& p = t_.p;
  if (!p.has_grid || p.grid.size() == 0 || !detail::anyEmitter(t_.scene, lights.emissive())) return true;
  const detail::EmitterSampler sampler(t_.scene, t_.accel, lights.emissive());
  detail::sampleEmittersSh(sampler, p.grid, p.grid_fill, bands, kGridEmitterSamples, grid_, rays);
  return true;
}

void EmissionState::invalidate() {
  emission_key_.valid = surfel_key_.valid = texel_key_.valid = grid_key_.valid = false;
}

}  // namespace lightlink::relight
