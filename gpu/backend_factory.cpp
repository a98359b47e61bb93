#include "gpu/backend_factory.h"

#include <fmt/format.h>

namespace lightlink::gpu {

Expected<BackendChoice> parseBackendChoice(std::string_view text, std::string_view field) {
  if (text == "auto") return BackendChoice::kAuto;
  if (text == "cpu") return BackendChoice::kCpu;
  if (text == "gpu") return BackendChoice::kGpu;
  return invalidInput("{}: '{}' is not one of cpu, gpu, auto", field, text);
}

#ifndef LIGHTLINK_HAVE_GPU
const GpuProbe& probeGpu() {
  static const GpuProbe probe{false, "", "", "built without the GPU backend (LIGHTLINK_BUILD_GPU=OFF)"};
  return probe;
}
#endif

Expected<std::unique_ptr<relight::RelightBackend>> makeBackend(BackendChoice choice, const scene::Scene& scene,
                                                               const rt::Accel& accel,
                                                               const precompute::Precomputation& p,
                                                               links::LinksView lightmap_links,
                                                               links::LinksView grid_links, std::string* note) {
  if (choice != BackendChoice::kCpu) {
    const GpuProbe& probe = probeGpu();
    if (probe.available && probe.software && choice == BackendChoice::kAuto) {
      if (note) *note = fmt::format("cpu: fallback, the only GL context is a software renderer ({})", probe.renderer);
    } else if (probe.available) {
#ifdef LIGHTLINK_HAVE_GPU
      auto gpu = makeGpuBackend(scene, accel, p, lightmap_links, grid_links);
      if (gpu) {
        if (note) *note = fmt::format("gpu: {}", probe.renderer);
        return gpu;
      }
      if (choice == BackendChoice::kGpu) return gpu.status();
      if (note) *note = fmt::format("cpu: fallback, GPU backend failed: {}", gpu.status().message());
#endif
    } else if (choice == BackendChoice::kGpu) {
      return unsupported("backend: gpu requested but unavailable: {}", probe.error);
    } else if (note) {
      *note = fmt::format("cpu: fallback, no usable GPU context ({})", probe.error);
    }
  } else if (note) {
    *note = "cpu: requested";
  }
  return relight::makeCpuBackend(scene, accel, p, lightmap_links, grid_links);
}

}  // namespace lightlink::gpu
