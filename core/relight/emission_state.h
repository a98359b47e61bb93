// EmissionState: the light that depends on emission alone — the emitted radiosity per surfel
// and the emitters' direct light sampled at the surfels, at the lightmap caches and at the
// grid caches — computed when the emissive overrides (or a sample or band count) change and
// reused while they hold. Emitter sampling is the bulk of a relight (N shadow rays per
// texel), and an editor moving punctual lights or the sky never changes it; a change of
// emissive strengths or colours alone rescales the per-material layers it keeps
// (emitter_layers.h) instead of sampling again. Owned by the relight pipeline (pipeline.h)
// for every backend; a backend with its own emitter tracer (emitter_tracer.h, the GPU's)
// runs the sampling, with the same samples, where it can.
#pragma once

#include <cstdint>
#include <string>
#include <span>
#include <vector>

#include <glm/glm.hpp>

#include "core/relight/emitter_layers.h"
#include "core/relight/emitter_tracer.h"
#include "core/relight/light_set.h"
#include "core/relight/passes.h"
#include "core/relight/relight.h"
#include "core/relight/scene_tables.h"

namespace lightlink::relight {

// Emitted radiosity pi * L_e per surfel (tree order) after the light set's overrides.
void surfelEmissionInto(const SceneTables& tables, const LightSet& lights, std::vector<glm::vec3>& out);

using EmitterUpdate = detail::LayeredEmitterLight::Update;

class EmissionState {
 public:
  explicit EmissionState(const SceneTables& tables) : t_(tables) {}

  // The backend's tracer for the sampling (null: the host samples every product), and the
  // log its runs go to (both outlive this).
  void setTracer(detail::EmitterTracer* tracer, detail::EmitterTraceLog* log) {
    tracer_ = log ? tracer : nullptr, log_ = log;
  }

  // pi * L_e per surfel; true when it changed.
  bool updateEmission(const LightSet& lights);
  // Each of the emitters' products below is kept while the emissive overrides (and its
  // sample or band count) hold, rescaled when only strengths or colours changed, else sampled.
  // The emitters' direct irradiance at every surfel, kSurfelEmitterSamples shadow rays each
  // (zeros when no triangle emits): added to the surfels' punctual light before the pull.
  // Its rays are not counted in RelightCounts::shadow_rays (texel and grid rays are).
  EmitterUpdate updateSurfels(const LightSet& lights);
  // The emitters' direct irradiance per lightmap cache, `samples` shadow rays each.
  EmitterUpdate updateTexels(const LightSet& lights, int samples, std::size_t& rays);
  // The emitters' radiance SH per grid cache (3 * bands^2 floats each, the grid's fill
  // applied; empty without a grid or when no triangle emits), kGridEmitterSamples rays each.
  EmitterUpdate updateGrid(const LightSet& lights, int bands, std::size_t& rays);
  // Texels take no emitter light (not baked, or a finer direct layer takes it).
  void dropTexels();
  void invalidate();

  std::span<const glm::vec3> emission() const { return emission_; }
  std::uint64_t emissionGeneration() const { return emission_generation_; }
  std::span<const glm::vec3> surfels() const { return surfel_.rgb(); }
  EmitterTexels texels() const { return {texel_.rgb(), texel_generation_}; }
  const std::vector<float>& grid() const { return grid_; }
  std::size_t emitterTriangles() const { return texel_.triangles(); }

  static constexpr int kSurfelEmitterSamples = 16;
  static constexpr int kGridEmitterSamples = 64;

 private:
  const SceneTables& t_;
  detail::EmitterTracer* tracer_ = nullptr;
  detail::EmitterTraceLog* log_ = nullptr;
  bool emission_valid_ = false;
  std::vector<EmissiveOverride> emission_overrides_;
  std::vector<glm::vec3> emission_;
  detail::LayeredEmitterLight surfel_, texel_, grid_light_;
  std::vector<float> grid_;  // grid_light_ filled
  std::uint64_t emission_generation_ = 0, texel_generation_ = 0;
};

}  // namespace lightlink::relight
