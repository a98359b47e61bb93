// Emitter direct light (internal to core/relight): soft-shadowed irradiance that emissive
// surfaces (area lights) send straight to a receiver, by Monte Carlo over the emitters.
//
// The links carry emitted light too, but as a cut of coarse tree nodes: a small lamp a few
// texels from a receiver becomes one blurred node and its shadow a smudge. The lightmap's
// `direct` output instead samples the emitting triangles themselves, each sample checked by
// one shadow ray, so penumbrae come from the true emitter geometry; the
// relight then leaves the emitters' first gather out of the lightmap SH (docs/relight.md).
//
// Estimator, per receiver at x with unit normal n: pick triangle t with probability
// P(t) = w_t / W, w_t = A_t (R + G + B of its emission bound), then a direction uniform in
// the solid angle Omega_t it subtends (Arvo 1995): E += L_e(q) V(x, q) cos_r Omega_t / P(t).
// Solid-angle sampling has no 1/d^2 peak, so a receiver next to an emitter (a wall touching
// a lamp) is as quiet as a far one; triangles subtending < 3e-4 sr (far: the construction
// loses its digits) or > 6.22 sr (x nearly in their plane) use uniform area sampling,
// E += L_e V cos_r cos_e / d^2 * A_t / P(t). With few emitting triangles (kLocalPickMax) P(t)
// is the receiver's own: w_t(x) = w_t / max(d^2, A_t), 0 below its horizon or behind a
// one-sided emitter, so a texel next to a weak lamp does not spend its samples on a strong
// one it barely sees (test ReceiversDoNotSpendSamplesOnEmittersThatCannotLightThem). Samples are a Hammersley set (stratified in the
// pick, so emitters get samples in proportion to power, and within each triangle) rotated
// per receiver by its seed (Cranley-Patterson), so every receiver's result is a pure
// function of (position, normal, N, seed): deterministic for any thread count. Units: L_e
// radiance (docs/units.md), E irradiance (lux-equivalent).
//
// Grid caches (points in free space, no normal) take the same samples over the whole sphere
// (no horizon, no cos_r) and project them into SH instead: L_lm += L_e V Y_lm(w) Omega_t / P(t)
// (radianceSh), so a small lamp reaches the irradiance volume as sharply as it reaches a texel.
//
// Layers: given a layer per material, each sample's contribution goes to its triangle's
// material's layer, so the caller can keep the light of each emissive material apart and
// rescale it when only that material's strength or colour changes (emitter_layers.h).
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include <glm/glm.hpp>

#include "core/relight/light_set.h"
#include "core/rt/accel.h"
#include "core/scene/scene.h"

namespace lightlink::relight::detail {

// True when some static triangle emits after the overrides (what the effects plan needs;
// per mesh, no triangle loop).
bool anyEmitter(const scene::Scene& scene, std::span<const EmissiveOverride> overrides);

// A receiver's Cranley-Patterson rotation (r0, r1) of the Hammersley set, from its seed:
// sample i is at (i / N + r0, radicalInverse(i, 2) + r1) mod 1.
glm::vec2 emitterRotation(std::uint64_t seed);
// The seeds of the receivers EmissionState and the direct layer sample: a surfel by its index,
// a lightmap point by its texel or'ed with a salt, a grid cache by its index.
std::uint64_t surfelEmitterSeed(std::size_t surfel);
std::uint64_t texelEmitterSeed(std::uint32_t texel, std::uint64_t salt);
std::uint64_t gridEmitterSeed(std::size_t cache);

class EmitterSampler {
 public:
  // Collects the static triangles whose emission bound is > 0 after `overrides` (dynamic
  // meshes are neither in the BVH nor surfels: nothing baked depends on them).
  // `layer_of_material` (indexed by material; empty: one layer) gives each triangle the
  // layer its contributions go to; it must cover every emitting triangle's material.
  EmitterSampler(const scene::Scene& scene, const rt::Accel& accel, std::span<const EmissiveOverride> overrides,
                 std::span<const int> layer_of_material = {});

  std::size_t triangleCount() const { return p0_.size(); }
  int layerCount() const { return layers_; }

  // The per-triangle tables, for a backend that runs the same estimator itself
  // (emitter_tracer.h). All spans have triangleCount() entries.
  struct Tables {
    std::span<const glm::vec3> p0, e1, e2, normal;
    std::span<const std::uint8_t> double_sided;
    std::span<const std::uint16_t> layer;
    std::span<const double> cdf, weight, area;  // power pick, w_t, A_t (m^2)
    std::span<const float> inv_pick, inv_pdf_area;
  };
  Tables tables() const;
  // True when every triangle's radiance is one constant (no emissive texture to sample).
  bool uniformRadiance() const;
  // L_e of triangle e where it is constant (uniformRadiance()), after the overrides.
  glm::vec3 constantRadiance(std::size_t e) const { return radianceAt(e, glm::vec2(0.0f)); }

  // Per-call scratch (one per task), so the hot loop does not allocate.
  struct Scratch {
    std::vector<rt::Ray> rays;
    std::vector<glm::vec3> contrib;
    std::vector<glm::vec3> dir;              // unit direction of each sample (radianceSh)
    std::vector<std::uint8_t> blocked;
    std::vector<std::uint16_t> layer;        // layer of each sample's triangle
    std::vector<double> cdf;                 // per-receiver pick (few emitters), see irradiance()
    std::vector<float> inv_pick, inv_pdf_area;
  };
  // Up to this many emitting triangles, each receiver picks them by its own estimate of what
  // they send it (power over squared distance, zero for a triangle below its horizon or
  // showing it its back); beyond, by power alone. Unbiased either way: a triangle gets
  // weight 0 only where it cannot contribute.
  static constexpr std::size_t kLocalPickMax = 64;

  // Irradiance at `position` (unit `normal`) from the emitters, with `samples` samples, per
  // layer: writes out[layerCount()]; adds the shadow rays traced to `rays`.
  void irradiance(glm::vec3 position, glm::vec3 normal, int samples, std::uint64_t seed, Scratch& scratch,
                  glm::vec3* out, std::size_t& rays) const;
  // SH (`bands` bands, 3 planar channels, docs/sh.md) of the radiance arriving at `position`
  // from the emitters over the whole sphere, with `samples` samples, per layer; *adds* to
  // out[layerCount() * 3 * bands^2] (layer-major) and the shadow rays traced to `rays`. A pure
  // function of (position, samples, seed), like irradiance().
  void radianceSh(glm::vec3 position, int bands, int samples, std::uint64_t seed, Scratch& scratch, float* out,
                  std::size_t& rays) const;

 private:
  // Draws the samples for a receiver with a unit `normal` (its hemisphere, weights with
  // cos_r) or none (nullptr: the whole sphere, no cosine), traces their shadow rays and
  // leaves L_e * weight and the direction of each of the first `count` samples in scratch,
  // scratch.blocked marking the shadowed ones. Returns count (samples that can contribute).
  std::size_t sample(glm::vec3 position, const glm::vec3* normal, int samples, std::uint64_t seed, Scratch& scratch,
                     std::size_t& rays) const;
  glm::vec3 radianceAt(std::size_t e, glm::vec2 barycentric) const;

  const scene::Scene& scene_;
  const rt::Accel& accel_;
  // One entry per emitting triangle: p = p0 + u e1 + v e2 (Embree's barycentrics).
  std::vector<glm::vec3> p0_, e1_, e2_;
  std::vector<glm::vec3> normal_;        // unit geometric normal, the glTF front side
  std::vector<std::uint32_t> mesh_, triangle_;
  std::vector<std::uint8_t> double_sided_;
  std::vector<std::uint8_t> replace_;    // 1: radiance = value_ (kRadiance override)
  std::vector<std::uint8_t> textured_;   // 1: the emission is read from a texture
  std::vector<std::uint16_t> layer_;     // layer of each triangle
  int layers_ = 1;
  std::vector<glm::vec3> value_;         // kRadiance radiance, or the kScale factor (1 without override)
  std::vector<double> cdf_;              // cdf_[i] = sum_{j <= i} w_j / W; cdf_.back() = 1
  std::vector<float> inv_pick_;          // 1 / P(t) = W / w_t
  std::vector<float> inv_pdf_area_;      // 1 / pdf_A = A_t W / w_t, m^2
  std::vector<double> weight_, area_;    // w_t and A_t (m^2), for the per-receiver pick
};

}  // namespace lightlink::relight::detail
