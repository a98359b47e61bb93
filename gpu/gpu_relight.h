// GpuRelighter: the relight of core/relight (seed 000 sec 3) with OpenGL 4.5 compute passes
// on a headless EGL context (DESIGN.md sec 10; docs/gpu.md): the one relight pipeline
// (core/relight/pipeline.h) running the GPU's passes (GpuPasses, behind RelightPasses).
//
//   lights --shadow maps (raster)--> light_points.comp: surfel direct radiosity b0
//          --leaf_flux + pull.comp per tree level + radiosity.comp--> node radiosity
//          --cache_light.comp (projected fp16 or runtime links, + sky)--> cache SH
//          --[fill.comp, gather.comp: bounce, repeat pull + cache lighting]--
//          --light_points.comp (baked lights at lightmap caches + the emitters' direct)-->
//          --fill.comp, texels.comp, fill.comp (dilation)--> read back into RelightResult
//
// Everything static (surfels, tree, links as stored in the artifact, gather tables, fill
// plans, the scene's triangles for shadow maps) is uploaded once at creation; everything per
// relight stays on the GPU, and only what RelightResult carries is read back, through one
// persistently mapped staging buffer and a fence. The bounce stop test's two sums are copied
// to the staging buffer behind a fence while the GPU goes on with that bounce's pull and
// cache lighting, so the host waits only for work it issued anyway. Differences from the
// CPU: shadow maps instead of ray-traced shadows for punctual lights (measured in tests/gpu
// and bench/gpu), fp32 sums in a different order, no incremental relight of one changed
// light (a full relight instead). The emitters' sampled light is sampled on the GPU too
// (gpu/emitter_sampling.h: a compute shader over a flat BVH), read back into the pipeline's
// per-material layers and uploaded again when it changes.
#pragma once

#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "core/common/status.h"
#include "core/relight/relight.h"
#include "gpu/egl_context.h"

namespace lightlink::gpu {

struct GpuOptions {
  int shadow_resolution = 1024;    // texels per shadow-map view side
  int lanes = 8;                   // threads per cache in cache lighting (1, 2, 4, ..., 64)
  // Shadow biases: a constant in units of the scene's bounding-box diagonal, plus multiples
  // of the shadow texel's world footprint at the point (docs/gpu.md "Tolerances").
  float bias_scene = 2e-4f;
  float normal_offset_texels = 1.5f;
  float slope_bias_texels = 1.0f;
  // Sample the emitters on the GPU (gpu/emitter_sampling.h); false: on the host, as the CPU
  // backend does (parity tests that need identical emitter light on both backends).
  bool emitter_sampling = true;
  // Threads per point in the emitter sampling (1, 2, 4, ..., 32), its samples spread over
  // them: 32 fills a GPU with few points (one workgroup per point), 1 runs a point's samples
  // in one thread (fewer triangle set-ups per point). Results are identical for any value.
  int emitter_lanes = 32;
};

class GpuRelighter {
 public:
  // Static inputs must outlive the relighter (as for relight::Relighter).
  static Expected<std::unique_ptr<GpuRelighter>> create(const scene::Scene& scene, const rt::Accel& accel,
                                                        const precompute::Precomputation& p,
                                                        links::LinksView lightmap_links, links::LinksView grid_links,
                                                        const GpuOptions& options = {});
  ~GpuRelighter();
  GpuRelighter(const GpuRelighter&) = delete;
  GpuRelighter& operator=(const GpuRelighter&) = delete;

  relight::EffectsPlan plan(const relight::LightSet& lights, const relight::RelightOptions& options) const;
  bool incrementalFor(const relight::LightSet& lights, const relight::RelightOptions& options) const;
  // RelightResult::timings holds GPU time per stage (timer queries) and host time for the
  // CPU parts (readback, and emitter sampling where the GPU declines it).
  Status relightInto(const relight::LightSet& lights, const relight::RelightOptions& options,
                     relight::RelightResult& out);
  void invalidate();
  const GlContextInfo& info() const;

  // Benchmark yardstick, in this context: seconds (GPU timer) to read `bytes` once with a
  // coalesced compute kernel (copy = false) or to copy them (copy = true); median of `repeats`.
  Expected<double> measureStream(std::size_t bytes, bool copy, int repeats);

 private:
  struct Impl;
  explicit GpuRelighter(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

}  // namespace lightlink::gpu
