// The points of the accuracy study: one factor at a time around a base point, plus the
// quality presets.
//
// The base point is the "medium" preset (DESIGN.md sec 11's reference workload: nS 32k,
// nL 128, 3 bands, 1024 link rays, 128^2 atlas) relit with the projected links and bounces
// run to convergence (cap 64, threshold 1e-4), so that no factor's error hides behind an
// unconverged bounce count. Each factor then moves alone: nS, nL, link bands, link rays,
// hierarchy builder, cache density (atlas resolution, i.e. texel size), link form (runtime
// projection at 2/3/4 bands) and bounce count. "candidate" points combine factors (fewer
// surfels with more links, as the one-factor sweeps suggest) for the preset derivation. Link form and bounces only change the relight,
// so they reuse the base precomputation.
#pragma once

#include <string>
#include <vector>

#include "core/precompute/precompute.h"
#include "core/relight/relight.h"

namespace lightlink::bench {

struct StudyPoint {
  std::string factor;  // "base", "surfels", "links", "bands", "rays", "builder", "density", "form", "bounces", "preset"
  std::string value;   // the factor's value, as printed in the CSV
  precompute::PrecomputeOptions pre;
  relight::RelightOptions rel;
  // Bounces of the reference it is compared with; -1 = all (Russian roulette). The
  // "single" diagnostic compares a relight with no bounce feedback (max_bounces 0) with the
  // reference's single-bounce light (1): first-bounce transport error alone.
  int reference_bounces = -1;
};

enum class SweepSize {
  kFull,     // every factor at every value (a 16-core machine: tens of minutes per scene)
  kReduced,  // two or three values per factor, the presets (2 cores: minutes)
  kPresets,  // the three presets only
  kBase,     // the base point only
  kDiagnose, // base, and first-bounce transport (relight bounces 0 vs 1-bounce reference) at
             // the base and at the best value of each factor but density: for a light set with punctual
             // lights only (emitters need a bounce to reach the caches)
};

// The relight options every point starts from: projected links, bounces to convergence.
relight::RelightOptions baseRelightOptions();

std::vector<StudyPoint> studyPoints(SweepSize size);

}  // namespace lightlink::bench
