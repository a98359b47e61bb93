// ReferenceRenderer: the ground truth every accuracy number of lightlink is measured against
// (DESIGN.md sec 7).
//
// An unbiased Monte Carlo path tracer on the same Embree accel, scene, materials, light set
// and units as the baker, computing irradiance (incident, cosine-weighted, lux per linear RGB
// channel; docs/units.md) at arbitrary points and normals: the exact lightmap cache
// positions, texels and grid points. Surfaces are Lambertian with albedo
// baseColorFactor * baseColorTexture (scene::albedoAt) and emit radiance
// scene::emissionAt after the LightSet's emissive overrides; punctual lights are the
// LightSet's, evaluated by scene::irradianceFrom; escaping rays see the LightSet's sky (its
// SH radiance when given, else the uniform radiance). Back faces of single-sided materials
// are black and stop paths (they are the inside of something), as in link generation.
//
// Estimator (docs/reference.md has the derivation): cosine-weighted sampling of the
// hemisphere around the query normal, E = pi * mean(L); the punctual lights' direct
// irradiance at the query point is computed once, exactly (one shadow ray per light), so
// it carries no error; at every path vertex, next-event estimation for punctual lights and
// for emissive triangles (chosen by area * radiance bound), the latter combined with the
// cosine sampling by multiple importance sampling (power heuristic); Russian roulette after
// three bounces with survival min(1, max albedo channel). Nothing is clamped. The only
// truncation is the safety cap `max_bounces`, and paths cut there are counted per point.
//
// "direct" is light that reaches the query point without any bounce (punctual lights,
// emitters and sky seen directly); "indirect" everything that bounced off a surface at
// least once. The baker's caches hold emitted + indirect light, its baked direct the
// punctual part of the baked lights: see docs/reference.md for how to compare.
//
// Each point runs in rounds until its standard error (from the sample variance) falls
// below `target_rel_error` of its irradiance, or it reaches `max_samples`, or the call's
// time budget runs out. Sample j of point i draws from a stream seeded by (seed, i, j),
// and samples are summed in fixed blocks in a fixed order, so results are bit-identical for
// any thread count (unless the time budget cuts a round short, which depends on speed).
#pragma once

#include <cstdint>
#include <memory>
#include <span>
#include <vector>

#include <glm/glm.hpp>

#include "core/common/progress.h"
#include "core/common/status.h"
#include "core/relight/light_set.h"
#include "core/rt/accel.h"
#include "core/scene/scene.h"

namespace lightlink::reference {

struct ReferenceOptions {
  int min_samples = 64;             // per point, before the error test is trusted (>= 2)
  int max_samples = 1 << 16;        // per point (>= min_samples)
  // Stop a point when std error <= target * irradiance in every channel, both taken relative
  // to the brightest channel of the total. 0: run every point to max_samples.
  float target_rel_error = 0.01f;
  double time_budget_s = 0.0;       // wall clock for the whole call; 0 = unlimited
  // Safety cap on bounces per path (0 = direct light only). Russian roulette ends paths long
  // before it unless albedo is near 1; paths that reach it are counted in truncated_paths.
  int max_bounces = 256;
  std::uint64_t seed = 1;
};

// Points and the unit normals of the hemispheres they gather over, world space (metres).
// A point on a surface should lie on it (the renderer offsets rays by Accel::offsetOrigin
// along the normal); a grid point may float anywhere, queried once per normal of interest.
struct Query {
  std::span<const glm::vec3> position;
  std::span<const glm::vec3> normal;
};

// Irradiance in lux per linear RGB channel. total = direct + indirect, and direct =
// direct_punctual + the emitted part (emitters and sky seen directly).
struct IrradianceEstimate {
  glm::vec3 total{0.0f};
  glm::vec3 direct{0.0f};
  glm::vec3 indirect{0.0f};
  glm::vec3 direct_punctual{0.0f};   // exact (shadow ray per light): no error
  // One standard error of the mean, per channel (infinite below 2 samples, which only a spent
  // time budget leaves). std_error_direct is that of the emitted part.
  glm::vec3 std_error_total{0.0f};
  glm::vec3 std_error_direct{0.0f};
  glm::vec3 std_error_indirect{0.0f};
  std::uint32_t samples = 0;         // paths traced
  std::uint32_t truncated_paths = 0; // paths cut by max_bounces (0 unless albedo ~ 1)
  std::uint64_t rays = 0;            // closest-hit + shadow rays traced for this point
  bool converged = false;            // reached target_rel_error (false at max_samples / budget)
};

class ReferenceRenderer {
 public:
  // `scene` and `accel` must outlive the renderer; `accel` must be built from `scene` (with
  // or without its dynamic meshes: emitters are taken from the meshes the accel holds). The
  // light set is copied. Fails with kInvalidInput when an emissive override names a material
  // the scene lacks or the accel does not match the scene.
  static Expected<ReferenceRenderer> create(const scene::Scene& scene, const rt::Accel& accel,
                                            const relight::LightSet& lights);

  ReferenceRenderer(ReferenceRenderer&&) noexcept;
  ReferenceRenderer& operator=(ReferenceRenderer&&) noexcept;
  ~ReferenceRenderer();

  // One estimate per query point. Fails with kInvalidInput on bad options (naming the field)
  // or a bad query (mismatched sizes, non-finite values, zero normal; naming the index), with
  // kInternal when `progress` reports cancellation.
  Expected<std::vector<IrradianceEstimate>> irradiance(const Query& query, const ReferenceOptions& options,
                                                       Progress* progress = nullptr) const;

  static Status validate(const ReferenceOptions& options);

  // Emissive triangles the renderer samples for next-event estimation (0: none emits).
  std::size_t emitterTriangleCount() const;

 private:
  struct Impl;
  explicit ReferenceRenderer(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

}  // namespace lightlink::reference
