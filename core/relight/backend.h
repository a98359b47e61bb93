// RelightBackend: the one interface behind which the CPU relight (core/relight) and the GPU
// relight (gpu/, EGL + GL compute, shaders/) sit, so `lightlink bake --backend` and the
// daemon pick one at run time and the rest of the code never knows which ran.
//
// A backend is bound to one resident scene (scene, accel, precomputation and link views,
// which must outlive it). `relightInto` has the contract of Relighter::relightInto: the
// result names the light-set version it is for and, in RelightResult::backend, the backend
// that produced it ("cpu" or "gpu"). Backends are not thread-safe; the daemon runs one
// relight worker per scene. The factory that can also make a GPU backend lives with the GPU
// code (gpu/backend_factory.h), because core/ knows nothing of GL.
#pragma once

#include <memory>
#include <string_view>

#include "core/common/status.h"
#include "core/relight/relight.h"

namespace lightlink::relight {

class RelightBackend {
 public:
  virtual ~RelightBackend() = default;
  // "cpu" or "gpu".
  virtual std::string_view name() const = 0;
  virtual EffectsPlan plan(const LightSet& lights, const RelightOptions& options) const = 0;
  virtual Status relightInto(const LightSet& lights, const RelightOptions& options, RelightResult& out) = 0;
  // Whether relightInto with these would relight one changed light incrementally.
  virtual bool incrementalFor(const LightSet& lights, const RelightOptions& options) const = 0;
  // Forgets the last light set: the next relight is a full one.
  virtual void invalidate() = 0;
};

// The CPU backend: a Relighter behind the interface.
Expected<std::unique_ptr<RelightBackend>> makeCpuBackend(const scene::Scene& scene, const rt::Accel& accel,
                                                         const precompute::Precomputation& p,
                                                         links::LinksView lightmap_links,
                                                         links::LinksView grid_links);

}  // namespace lightlink::relight
