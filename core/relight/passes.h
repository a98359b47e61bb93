// RelightPasses: the per-pass kernels of one relight backend — the CPU's (cpu_passes.h) or
// the GPU's (gpu/gpu_relight.h) — behind which RelightPipeline (pipeline.h) runs every
// relight, as pbrt-v4 splits an integrator from the back ends that run its kernels. The
// pipeline owns the pass order, the effects plan, the bounce loop and its stop rule, the
// memo of the last light set and the light that depends on emission alone; a backend owns
// its buffers and the kernels that fill them, and records its own stage timings, pass and
// work counts into the result.
//
// One full relight calls: begin, setEmission (when it changed), surfelDirect, pullAndLight,
// then per bounce gather, bounceSums and pullAndLight, then cacheDirect and texels; a warm
// one (RelightFrame::warm) skips the first pullAndLight, its first gather reading the caches
// of the last relight. A relight
// where exactly one light changed calls begin, relightChange and texels on a backend that
// supports it — with bounces on (incrementalBounces), propagateChange per round between the
// two; an unchanged light set calls begin and texels only. Between relights a backend keeps
// its per-cache state (the pipeline relies on it for both shortcuts).
#pragma once

#include <chrono>
#include <cstdint>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include <glm/glm.hpp>

#include "core/common/status.h"
#include "core/relight/emitter_tracer.h"
#include "core/relight/light_set.h"
#include "core/relight/relight.h"

namespace lightlink::relight {

// The inputs every pass of one relight sees.
struct RelightFrame {
  const LightSet& lights;
  const RelightOptions& options;
  const EffectsPlan& plan;
  int bands = 0;               // output SH bands
  std::size_t stride = 0;      // floats per cache: 3 * bands^2
  bool coarse_direct = true;   // direct light goes to the texels (no finer direct layer)
  // Per channel, the nc_out x nc_links matrix turning a cache's sky visibility into sky
  // radiance (pipeline.cpp); set when plan.sky.
  const std::vector<float>* sky_matrix = nullptr;
  // Warm start (RelightOptions::warm_start): surfelDirect keeps b, the last solution, for the
  // first gather to measure its change against, and that gather reads the kept caches.
  bool warm = false;
};

// A bounce's stop test inputs: flux the bounce added and the total, summed in a fixed order.
struct BounceSums {
  double added = 0.0, total = 0.0;
};

// Exactly one light added, removed or modified since the last relight.
struct LightChange {
  enum class Kind { kModified, kAdded, kRemoved };
  Kind kind = Kind::kModified;
  std::size_t index = 0;           // in the new list (added, modified) or the old one (removed)
  scene::Light old_light, new_light;  // a zero-intensity light stands for "no light"
  bool old_baked = false, new_baked = false;
};

// The emitters' direct light per lightmap cache, and a number that changes whenever it does.
struct EmitterTexels {
  std::span<const glm::vec3> value;  // empty: not baked into the texels
  std::uint64_t generation = 0;
};

// Runs `body` and records its wall time as stage `stage` of `res` (host-side stages; the GPU
// records its own with timer queries).
template <class F>
void timedStage(RelightResult& res, std::string stage, F&& body) {
  const auto t0 = std::chrono::steady_clock::now();
  body();
  res.timings.push_back({std::move(stage), std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count()});
}

class RelightPasses {
 public:
  virtual ~RelightPasses() = default;
  virtual std::string_view backend() const = 0;  // "cpu" or "gpu"
  virtual std::string kernelName(const RelightOptions& options) const = 0;  // "avx2", "glsl-lanes8", ...

  // The backend's own emitter sampling (emitter_tracer.h), or null: the host samples.
  virtual detail::EmitterTracer* emitterTracer() { return nullptr; }

  // First in every relight: per-relight state reset, buffers sized for frame.stride.
  virtual Status begin(const RelightFrame& frame) = 0;
  // The emitted radiosity pi * L_e per surfel (after overrides); `generation` changes with it.
  virtual Status setEmission(std::span<const glm::vec3> emission_b, std::uint64_t generation) = 0;
  // (a) Surfel direct radiosity b0 = albedo * E and b = b0 (frame.warm: b is kept), with E
  // the punctual lights' irradiance (or options.surfel_irradiance when given) plus
  // `surfel_emit`, the emitters'. frame.sky_matrix is ready by then.
  virtual Status surfelDirect(const RelightFrame& frame, std::span<const glm::vec3> surfel_emit,
                              RelightResult& res) = 0;
  // (b) Pull b up the tree, (c) light the lightmap caches through their links (and the sky),
  // and the grid caches when `grid`. Stage names start with `stage_prefix`.
  virtual Status pullAndLight(const RelightFrame& frame, const std::string& stage_prefix, bool grid,
                              RelightResult& res) = 0;
  // (d) Bounce `bounce`: fill the lightmap caches (and the grid's when `fill_grid`), then each
  // surfel gathers its caches' irradiance: b = b0 + albedo * E_indirect.
  virtual Status gather(const RelightFrame& frame, int bounce, bool fill_grid, RelightResult& res) = 0;
  // The last gather's sums. With sumsLag() they may be waited for only after the next
  // pullAndLight was issued (the GPU overlaps their readback with it).
  virtual Expected<BounceSums> bounceSums() = 0;
  virtual bool sumsLag() const { return false; }
  // (f) Direct light per lightmap cache: the baked punctual lights (when frame.coarse_direct)
  // plus `emitter`.
  virtual Status cacheDirect(const RelightFrame& frame, const EmitterTexels& emitter, RelightResult& res) = 0;
  // (e) Fill, texels, dilation: writes res.lightmap_sh, texel_valid, direct (when
  // frame.coarse_direct), grid_sh (the links' part, when plan.grid) and surfel_radiosity (the
  // reflected part b), and the texel counts.
  virtual Status texels(const RelightFrame& frame, RelightResult& res) = 0;

  // Incremental relight of one changed light: only what the change reaches. With bounces
  // off, the surfels it lights, their tree paths and the caches linked to them are rewritten
  // (the same sums as a full relight). With bounces on (frame.plan.bounces), relightChange
  // adds the change of direct light to the last converged solution and pushes it to the
  // caches, then each propagateChange round lets the surfels that read a changed cache gather
  // again and pushes their change on, until the pipeline's stop rule ends it: the change
  // travels through the bounces instead of the whole solution being iterated again.
  virtual bool incremental() const { return false; }
  virtual bool incrementalBounces() const { return false; }
  virtual Status relightChange(const RelightFrame& frame, const LightChange& change,
                               std::span<const glm::vec3> surfel_emit, const EmitterTexels& emitter,
                               RelightResult& res);
  // One round of the propagation: the flux it changed (`added`, as a bounce's) and the total.
  virtual Expected<BounceSums> propagateChange(const RelightFrame& frame, int round, RelightResult& res);
};

}  // namespace lightlink::relight
