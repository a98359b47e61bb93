// The GPU relight behind relight::RelightBackend, and probeGpu(): the glue between
// backend_factory.h and GpuRelighter.
#include <mutex>

#include "gpu/backend_factory.h"
#include "gpu/gpu_relight.h"

namespace lightlink::gpu {
namespace {

class GpuBackend final : public relight::RelightBackend {
 public:
  explicit GpuBackend(std::unique_ptr<GpuRelighter> r) : relighter_(std::move(r)) {}
  std::string_view name() const override { return "gpu"; }
  relight::EffectsPlan plan(const relight::LightSet& lights, const relight::RelightOptions& options) const override {
    return relighter_->plan(lights, options);
  }
  Status relightInto(const relight::LightSet& lights, const relight::RelightOptions& options,
                     relight::RelightResult& out) override {
    return relighter_->relightInto(lights, options, out);
  }
  bool incrementalFor(const relight::LightSet& lights, const relight::RelightOptions& options) const override {
    return relighter_->incrementalFor(lights, options);
  }
  void invalidate() override { relighter_->invalidate(); }

 private:
  std::unique_ptr<GpuRelighter> relighter_;
};

}  // namespace

const GpuProbe& probeGpu() {
  static std::once_flag once;
  static GpuProbe probe;
  std::call_once(once, [] {
    auto ctx = GlContext::create();
    if (!ctx) {
      probe.error = ctx.status().message();
      return;
    }
    probe.available = true;
    probe.renderer = (*ctx)->info().renderer;
    probe.version = (*ctx)->info().version;
    for (const char* sw : {"llvmpipe", "softpipe", "SwiftShader", "swrast"})
      if (probe.renderer.find(sw) != std::string::npos) probe.software = true;
  });
  return probe;
}

Expected<std::unique_ptr<relight::RelightBackend>> makeGpuBackend(const scene::Scene& scene, const rt::Accel& accel,
                                                                  const precompute::Precomputation& p,
                                                                  links::LinksView lightmap_links,
                                                                  links::LinksView grid_links,
                                                                  const GpuOptions& options) {
  auto r = GpuRelighter::create(scene, accel, p, lightmap_links, grid_links, options);
  if (!r) return r.status();
  return std::unique_ptr<relight::RelightBackend>(std::make_unique<GpuBackend>(std::move(*r)));
}

}  // namespace lightlink::gpu
