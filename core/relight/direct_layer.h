// DirectLayer: the baked direct light at the precomputation's direct layer, a texel atlas of
// the same charts `direct_scale` times finer than the indirect caches (Unity's "lightmap
// resolution" vs "indirect resolution"; precompute::PrecomputeOptions::direct_scale).
//
// Direct light needs no links: per texel it is one shadow ray per baked punctual light plus
// emitter samples, so it can afford many more texels than the caches, and baked shadows come
// out crisp while the relight of the indirect stays as cheap as before. Each light's share is
// kept and reused while that light is unchanged (an editor moving one lamp re-traces only that
// lamp), the emitters' share while the emission is. The CPU Relighter and the GPU backend both
// use it; the punctual lights are traced on the CPU, the emitters on the backend's tracer when
// it has one (emitter_tracer.h). Deterministic for any thread count.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include <glm/glm.hpp>

#include "core/precompute/precompute.h"
#include "core/relight/emitter_tracer.h"
#include "core/relight/light_set.h"
#include "core/relight/relight.h"
#include "core/rt/accel.h"
#include "core/scene/scene.h"

namespace lightlink::relight {

class DirectLayer {
 public:
  // The scene, accel and precomputation must outlive the layer. Inactive when `p` has no
  // direct layer (PrecomputeOptions::direct_scale 1).
  DirectLayer(const scene::Scene& scene, const rt::Accel& accel, const precompute::Precomputation& p);
  DirectLayer(DirectLayer&&) noexcept;
  ~DirectLayer();

  bool active() const { return p_.hasDirectLayer(); }
  int width() const { return p_.direct_texels.width; }
  int height() const { return p_.direct_texels.height; }

  // Writes res.direct (width() x height() texels), res.direct_width/height and the direct
  // passes and counts: baked punctual lights with non-zero power (plan.baked_direct) plus
  // the emitters (plan.emissive_direct, options.emitter_samples each).
  void compute(const LightSet& lights, const RelightOptions& options, const EffectsPlan& plan, RelightResult& res);

  // The backend's tracer for the emitters (null: the host samples) and the log of its runs.
  void setTracer(detail::EmitterTracer* tracer, detail::EmitterTraceLog* log) {
    tracer_ = log ? tracer : nullptr, log_ = log;
  }

  // Forget the kept per-light terms (kLightState) or the emitter term too (kEverything).
  void invalidate(bool everything);

 private:
  struct State;
  const scene::Scene& scene_;
  const rt::Accel& accel_;
  const precompute::Precomputation& p_;
  std::unique_ptr<State> s_;
  detail::EmitterTracer* tracer_ = nullptr;
  detail::EmitterTraceLog* log_ = nullptr;
};

// The direct light at the lightmap's texels: res.direct itself, or a finer direct layer
// box-filtered down (the mean of each lightmap texel's valid direct texels, 0 where none is),
// for consumers that take one atlas size (the daemon's texture stream).
void directAtLightmapSize(const RelightResult& res, std::vector<glm::vec3>& out);

}  // namespace lightlink::relight
