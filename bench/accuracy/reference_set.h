// The accuracy study's ground truth: which points of a cache layout are compared, the
// path-traced reference there, and its on-disk cache.
//
// A *cache layout* is what fixes the lightmap caches' positions and normals: the scene,
// the unwrap (texel size / resolution) and the validity test. Every study point that keeps
// the layout (nS, nL, bands, rays, builder, link form, bounces) is compared at the same
// points against the same reference, computed once. A point that changes the layout
// (cache density) gets its own reference, computed once per layout and cached too: the
// study *recomputes* rather than resampling one fixed point set, so every error is measured
// exactly at cache positions, as DESIGN.md sec 7 asks.
//
// Two kinds of point per layout:
//   - centres: evenly strided valid lightmap caches (the baked value is the cache's own);
//   - midpoints: halfway between two horizontally adjacent valid caches on the same plane
//     (the baked value is their average, i.e. the bilinear lookup an engine does there).
//     The error at midpoints minus the error at centres is the cost of cache interpolation.
//
// The reference runs until the standard error of the *total* is <= 1 % (ReferenceOptions);
// points whose *indirect* standard error is still above 1 % of their indirect are re-run
// with a proportionally tighter target (buckets down to `min_target`), so the indirect
// errors the study reports are not dominated by the reference's own noise. The file is
// keyed by hash(scene bytes, light set bytes, layout string, reference options) and also
// checked point by point (positions and normals bit-identical), so a stale file is never used.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <glm/glm.hpp>

#include "core/common/status.h"
#include "core/precompute/precompute.h"
#include "core/reference/reference.h"
#include "core/relight/light_set.h"
#include "core/rt/accel.h"
#include "core/scene/scene.h"

namespace lightlink::bench {

struct ComparePoint {
  glm::vec3 position{0.0f};
  glm::vec3 normal{0.0f};
  std::uint32_t cache_a = 0, cache_b = 0;  // lightmap cache indices; a == b for a centre
  bool midpoint() const { return cache_a != cache_b; }
};

struct ReferenceSetOptions {
  int centres = 400;        // at most this many centre points
  int midpoints = 200;      // at most this many midpoints
  float target_rel_error = 0.01f;   // of the total, first pass
  float indirect_target = 0.01f;    // wanted std error of the indirect, relative to it
  float min_target = 0.0015f;       // tightest total target a re-run may use
  double time_budget_s = 0.0;       // per reference call; 0 = unlimited
  int max_bounces = 256;            // the reference's bounce cap (1: single-bounce light only)
  std::string cache_dir;            // "" = no disk cache
};

struct ReferenceSet {
  std::vector<ComparePoint> points;
  std::vector<reference::IrradianceEstimate> estimates;
  double seconds = 0.0;   // spent computing it (0 when read from disk)
  bool from_disk = false;
  std::string file;       // the cache file, when any
};

// The compared points of a layout: centres first, then midpoints.
std::vector<ComparePoint> selectPoints(const precompute::Precomputation& p, int centres, int midpoints);

// Reads the reference of `key_text` (scene + light set + layout) from the cache directory,
// or computes it at `points` and writes it there.
Expected<ReferenceSet> referenceFor(const scene::Scene& scene, const rt::Accel& accel,
                                    const relight::LightSet& lights, std::vector<ComparePoint> points,
                                    const std::string& key_text, const ReferenceSetOptions& options);

}  // namespace lightlink::bench
