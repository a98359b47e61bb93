#include "core/relight/emitter_tracer.h"

#include <fmt/format.h>

namespace lightlink::relight::detail {

bool traceEmitters(EmitterTracer* tracer, const EmitterSampler& sampler, const EmitterReceivers& points, int samples,
                   int bands, const std::string& stage, std::vector<float>& layers, std::size_t& rays,
                   EmitterTraceLog& log) {
  if (!tracer) return false;
  auto ran = tracer->trace(sampler, points, samples, bands, stage, layers, rays);
  if (ran && *ran) {
    log.timings.push_back({stage + "_gpu", tracer->lastSeconds()});
    return true;
  }
  log.notes.push_back(ran ? fmt::format("{}: sampled on the host ({})", stage, tracer->declined())
                          : fmt::format("{}: sampled on the host (the GPU failed: {})", stage, ran.status().toString()));
  return false;
}

}  // namespace lightlink::relight::detail
