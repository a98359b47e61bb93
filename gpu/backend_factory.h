// Backend choice for `lightlink bake --backend` and the daemon: cpu, gpu or auto.
//
// This is the one place that knows both backends: the CPU relight of core/relight and the
// EGL + GL compute relight of this folder. `auto` takes the GPU when a usable headless
// context exists (EGL, OpenGL 4.5 core, compute shaders) on a hardware GPU, and falls back to
// the CPU with a note saying why (no context, or only a software rasteriser such as Mesa's
// llvmpipe, which relights slower than the CPU code; `gpu` still runs on it, as CI does); an explicit `gpu` that cannot run is an error naming the reason. Builds
// without LIGHTLINK_BUILD_GPU compile only the CPU path and say so.
#pragma once

#include <memory>
#include <string>
#include <string_view>

#include "core/common/status.h"
#include "core/relight/backend.h"
#ifdef LIGHTLINK_HAVE_GPU
#include "gpu/gpu_relight.h"
#endif

namespace lightlink::gpu {

enum class BackendChoice { kAuto, kCpu, kGpu };

// "auto" | "cpu" | "gpu"; anything else is invalidInput naming `field`.
Expected<BackendChoice> parseBackendChoice(std::string_view text, std::string_view field = "backend");

struct GpuProbe {
  bool available = false;
  std::string renderer;  // GL_RENDERER, e.g. "llvmpipe (LLVM 15.0.6, 256 bits)"
  std::string version;   // GL_VERSION
  std::string error;     // why it is not available
  bool software = false; // the renderer is a CPU rasteriser (llvmpipe, softpipe, SwiftShader)
};

// Creates (once per process, then cached) a headless context and reports what it found.
const GpuProbe& probeGpu();

#ifdef LIGHTLINK_HAVE_GPU
// The GPU backend alone (no fallback): an error says what failed (no EGL display, no
// OpenGL 4.5 core context, a shader that does not compile, with its name and log).
Expected<std::unique_ptr<relight::RelightBackend>> makeGpuBackend(const scene::Scene& scene, const rt::Accel& accel,
                                                                  const precompute::Precomputation& p,
                                                                  links::LinksView lightmap_links,
                                                                  links::LinksView grid_links,
                                                                  const GpuOptions& options = {});
#endif

// The backend for one resident scene (inputs must outlive it). `note`, when given, receives
// a line for the report ("gpu: llvmpipe ..." or "cpu: fallback, no EGL display").
Expected<std::unique_ptr<relight::RelightBackend>> makeBackend(BackendChoice choice, const scene::Scene& scene,
                                                               const rt::Accel& accel,
                                                               const precompute::Precomputation& p,
                                                               links::LinksView lightmap_links,
                                                               links::LinksView grid_links,
                                                               std::string* note = nullptr);

}  // namespace lightlink::gpu
