// EmitterTracer: a backend's own run of the emitter sampler (the GPU's), in place of the host
// loop of EmitterSampler (internal to core/relight).
//
// EmissionState and DirectLayer hand each product's sampling to the backend's tracer when it
// has one: the same estimator, tables (EmitterSampler::tables()), receivers and per-receiver
// rotations (emitterRotation of the seeds in emitter_direct.h), writing the layers in the
// layout LayeredEmitterLight expects. A tracer may decline a sampler it cannot run (an emissive
// texture, alpha cut-outs it does not model); then the host samples, and the reason goes to
// the relight's plan notes. The device time of each run becomes a stage `<stage>_gpu` of the
// relight's timings (traceEmitters below keeps both for the pipeline).
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include <glm/glm.hpp>

#include "core/common/status.h"
#include "core/relight/emitter_direct.h"
#include "core/relight/relight.h"

namespace lightlink::relight::detail {

// The receivers of one product.
struct EmitterReceivers {
  std::span<const glm::vec3> position;
  std::span<const glm::vec3> normal;      // unit; empty: grid caches (whole sphere, SH)
  std::span<const std::uint8_t> valid;    // empty: every point; 0: the point gets zeros
  std::span<const glm::vec2> rotation;    // emitterRotation(seed) per point
};

class EmitterTracer {
 public:
  virtual ~EmitterTracer() = default;
  // Fills `layers` (points * layerCount() * stride floats) as EmitterSampler::irradiance
  // (bands == 0, stride 3) or radianceSh (bands > 0, stride 3 * bands^2) would per point,
  // and adds the shadow rays traced to `rays`. `stage` names the timed stage. Returns false
  // when it declines (why: declined()), an error when the backend failed.
  virtual Expected<bool> trace(const EmitterSampler& sampler, const EmitterReceivers& points, int samples, int bands,
                               const std::string& stage, std::vector<float>& layers, std::size_t& rays) = 0;
  // Why the last trace() declined (empty after one that ran).
  virtual const std::string& declined() const = 0;
  // Device seconds of the last trace() that ran (timer queries).
  virtual double lastSeconds() const = 0;
};

// What the tracer did in one relight: its stage times and why it left products to the host.
struct EmitterTraceLog {
  std::vector<StageTime> timings;
  std::vector<std::string> notes;
  void clear() { timings.clear(), notes.clear(); }
};

// Samples on `tracer` (null: returns false at once); true when it ran, recording stage
// `<stage>_gpu` in `log`; false, with a note, when it declined or failed (a failure is not
// fatal: the host then samples).
bool traceEmitters(EmitterTracer* tracer, const EmitterSampler& sampler, const EmitterReceivers& points, int samples,
                   int bands, const std::string& stage, std::vector<float>& layers, std::size_t& rays,
                   EmitterTraceLog& log);

}  // namespace lightlink::relight::detail
