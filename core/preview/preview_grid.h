// PreviewGrid: an irradiance volume lit without links, for the daemon's instant preview while
// the precompute (surfels, tree, links) still runs (seed 003, Radiance Hints, with the
// radiance caches sampled by a few rays each instead of from reflective shadow maps).
//
// Built once per scene from the loaded scene and its BVH: the grid is placed by the same rule
// and code as the precompute's grid caches (caches::placeGridCaches, validity included), and
// every valid probe traces `rays` directions over the sphere (links::LinkRays, the pattern link
// generation traces for grid caches). What each ray hit is kept: the point, the normal of the
// side the probe sees, the bounce albedo and the emission there, or the direction for a ray
// that escaped. Lighting a light set then needs no geometry work but shadow rays: per hit,
//
//   L = albedo / pi * (E_punctual + E_grid) + L_emitted          (E: irradiance, lux)
//
// with E_punctual the shadowed irradiance of every punctual light (relight::detail::
// shadowedLight, one shadow ray per light and hit), L_emitted the material's emission after
// the light set's overrides, and the sky's radiance for an escaped ray; the hit radiances are
// projected into SH (Monte Carlo, 4 pi / rays per sample). E_grid is Radiance Hints'
// multi-bounce: `bounces` more iterations read the irradiance of the previous iteration's grid
// at each hit (trilinear over valid probes, SH irradiance at the hit's normal), so light
// bounces between surfaces without links; trilinear interpolation across a thin wall can leak
// some of it (the linked result has no such leak). A back face of a single-sided surface is
// black, as link generation credits it to no surfel. Invalid probes are filled from their
// valid neighbours (caches::planGridFill), as a linked grid is.
//
// The output has the layout of relight::RelightResult::grid_sh: per probe 3 * bands^2 floats,
// R block then G then B, SH of incident radiance (docs/sh.md), the light of surfaces and the
// sky only (no radiance straight from a punctual light): a client decodes a preview grid
// exactly as a linked one. Deterministic: the same inputs give bit-identical output for any
// TBB thread count (probes in fixed chunks, every sum in a fixed order).
#pragma once

#include <cstdint>
#include <memory>
#include <vector>

#include <glm/glm.hpp>

#include "core/caches/caches.h"
#include "core/common/progress.h"
#include "core/common/status.h"
#include "core/lights/light_set.h"
#include "core/rt/accel.h"
#include "core/scene/scene.h"

namespace lightlink::preview {

struct PreviewOptions {
  // Rays per probe, rounded down to a square (a strata x strata stratified sphere), 4..4096.
  int rays = 256;
  // Total rays over all probes at most: above it the rays per probe are lowered (to no fewer
  // than 16), so a fine grid stays within the preview's time budget.
  std::uint64_t max_total_rays = 1u << 19;
  int bands = 3;         // SH bands of the output, 1..4
  // Radiance Hints grid-to-grid bounce iterations after the first, 0..8. Each costs an SH
  // projection, no rays; on the demo Cornell box 3 bring the mean irradiance within a few
  // percent of the converged linked grid (PreviewGrid.CloseToTheLinkedGrid prints it).
  int bounces = 3;
  std::uint64_t seed = 0x5eed;
  // Where the probes go: the precompute's grid options (spacing or resolution, volume,
  // validity rays), so that the preview's grid is the linked one when the scene has one.
  caches::GridCacheOptions grid;
};

struct PreviewStats {
  std::size_t probes = 0, probes_valid = 0;
  int rays_per_probe = 0;
  std::size_t rays = 0;         // probe rays traced by build()
  std::size_t shadow_rays = 0;  // by the last light()
  double place_seconds = 0.0, trace_seconds = 0.0;  // build()
  double light_seconds = 0.0;                       // the last light()
};

class PreviewGrid {
 public:
  // Places the probes and traces their rays. `accel` must be built from `scene` (static
  // meshes); it is kept by reference and must outlive the PreviewGrid; `scene` is read here
  // only. Fails with kInvalidInput on bad options (naming the field) and what
  // caches::placeGridCaches rejects; `progress` (optional) is polled for cancellation.
  static Expected<PreviewGrid> build(const scene::Scene& scene, const rt::Accel& accel, const PreviewOptions& options,
                                     const Progress* progress = nullptr);

  PreviewGrid(PreviewGrid&&) noexcept;
  PreviewGrid& operator=(PreviewGrid&&) noexcept;
  ~PreviewGrid();

  // The SH grid for `lights` into `grid_sh` (resized to probes * 3 * bands^2). Thread-safe
  // for concurrent calls (read-only state). Fails with kInvalidInput when an emissive
  // override names a material the scene does not have, or a light is not valid.
  Status light(const lights::LightSet& lights, std::vector<float>& grid_sh, PreviewStats* stats = nullptr) const;

  const caches::GridCaches& grid() const;
  int bands() const;
  // Counts and timings of build() (light() fields 0).
  const PreviewStats& buildStats() const;

 private:
  struct Impl;
  explicit PreviewGrid(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

}  // namespace lightlink::preview
