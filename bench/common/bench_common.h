// What the benchmarks share: robust statistics over repeated runs and the lights a benchmark
// uses on a scene, so that relight_bench, gpu_relight_bench and precompute_bench time the
// same thing the same way (docs/results.md quotes them side by side).
#pragma once

#include <chrono>
#include <cstdio>
#include <string>
#include <vector>

#include "core/precompute/precompute.h"
#include "core/relight/light_set.h"
#include "core/scene/scene.h"

namespace lightlink::bench {

using Clock = std::chrono::steady_clock;

// Seconds since t0 on the steady clock.
double secondsSince(Clock::time_point t0);

// The middle element (upper median for even sizes); 0 for an empty set. Medians, not means:
// the development VM is shared, and one preempted run must not move a figure.
double median(std::vector<double> v);

// Whether a step's result (a StatusOr) failed; if so its status goes to stderr (the
// benchmarks then exit with 2).
template <typename Result>
bool failed(const Result& result) {
  if (result) return false;
  std::fprintf(stderr, "%s\n", result.status().toString().c_str());
  return true;
}

// The "medium" workload's lightmap resolution (~10k lightmap caches on the shared scenes):
// the precompute benchmarks' default.
inline constexpr int kMediumResolution = 128;

// Applies one of the precompute flags the benchmarks share (--surfels N, --links N,
// --bands B, --rays N, --resolution R, --hierarchy hac|fast) to `options`; false when `flag`
// is none of them.
bool parsePrecomputeFlag(const std::string& flag, const char* value, precompute::PrecomputeOptions& options);

// The scene's own punctual lights, or, when it has none (zdm2), a 10 lux directional "sun"
// from above at a slant, so every scene is lit and benchmarks compare across backends.
relight::LightSet lightsOrSun(const scene::Scene& scene);

}  // namespace lightlink::bench
