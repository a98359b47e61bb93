// GpuEmitterSampling: the emitters' sampled light (core/relight/emitter_direct.h) run as a
// compute shader (shaders/emitter_points.comp), its shadow rays traced through a flat BVH of
// the scene (core/rt/flat_bvh.h, built with Embree's builder on first use and kept resident).
// It is the GPU backend's relight::detail::EmitterTracer: the relight pipeline hands it the
// surfels, lightmap caches, grid caches and direct-layer texels to sample; it writes the same
// layers the host sampler would (same samples, sums in the same order: docs/gpu.md) and
// reports its GPU time (the relight's stage `<stage>_gpu`). It declines (the host samples,
// and the relight's plan says why) scenes with alpha cut-outs among the shadow casters or
// emission read from a texture: neither is on the GPU.
// Needs the backend's GL context current on every call.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "core/relight/emitter_tracer.h"
#include "core/rt/accel.h"
#include "core/scene/scene.h"
#include "gpu/gl_objects.h"

namespace lightlink::gpu {

class GpuEmitterSampling final : public relight::detail::EmitterTracer {
 public:
  // scene and accel must outlive it. `lanes`: threads per point (a power of two in 1..32),
  // among which its samples are spread (GpuOptions::emitter_lanes).
  GpuEmitterSampling(const scene::Scene& scene, const rt::Accel& accel, int lanes = 32);
  ~GpuEmitterSampling() override;

  Expected<bool> trace(const relight::detail::EmitterSampler& sampler, const relight::detail::EmitterReceivers& points,
                       int samples, int bands, const std::string& stage, std::vector<float>& layers,
                       std::size_t& rays) override;
  const std::string& declined() const override { return declined_; }
  double lastSeconds() const override { return seconds_; }

 private:
  Status ensureBvh();

  const scene::Scene& scene_;
  const rt::Accel& accel_;
  int lanes_ = 32;
  GpuTimers timers_;  // its own: the result is read back (and timed) before trace() returns
  double seconds_ = 0.0;
  bool bvh_ready_ = false;
  bool has_bvh_ = false;
  std::size_t cutout_meshes_ = 0;
  GlBuffer nodes_, triangles_;
  std::vector<std::pair<std::string, GlProgram>> programs_;  // by variant key
  std::string declined_;
};

}  // namespace lightlink::gpu
