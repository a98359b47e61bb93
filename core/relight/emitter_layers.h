// Emitter light kept per emissive material ("layer"), sampled at unit strength. The light an
// emitter sends is linear in its radiance, so an emission change that keeps which materials
// emit and how (their texture, or a constant radiance) only rescales and re-sums the layers:
// no shadow ray is traced, and the result is the one a fresh sampling with that layout gives.
// Used by EmissionState (surfels, lightmap caches, grid) and the finer direct layer.
#pragma once

#include <cstddef>
#include <functional>
#include <span>
#include <vector>

#include <glm/glm.hpp>

#include "core/relight/emitter_direct.h"
#include "core/relight/light_set.h"
#include "core/rt/accel.h"
#include "core/scene/scene.h"

namespace lightlink::relight::detail {

// Memory the layers of one product may take; beyond it the product is one layer sampled at
// the real emission, resampled on every emission change.
inline constexpr std::size_t kEmitterLayerBudgetBytes = std::size_t(64) << 20;

// How the emitters are sampled for a set of emissive overrides.
struct EmitterLayout {
  // The overrides the sampler is built with: layered, kScale ones are left out (sampled at the
  // scene's own emission, the factor applied per layer) and kRadiance ones are at unit
  // radiance; not layered, the real overrides.
  std::vector<EmissiveOverride> sampled;
  std::vector<int> layer_of_material;  // per material, -1: emits nothing; empty: not layered
  int layers = 1;

  // One layer per emitting material when they fit kEmitterLayerBudgetBytes at
  // `bytes_per_layer` (what one layer of the product takes).
  static EmitterLayout of(const scene::Scene& scene, std::span<const EmissiveOverride> overrides,
                          std::size_t bytes_per_layer);
  bool layered() const { return !layer_of_material.empty(); }
  bool sameAs(const EmitterLayout& other) const;
  // The RGB factor of each layer under `overrides`.
  std::vector<glm::vec3> factors(std::span<const EmissiveOverride> overrides) const;
};

// One product of emitter light: `stride` floats per point, three planar channel blocks of
// stride / 3 (RGB irradiance: stride 3; SH: 3 * bands^2).
class LayeredEmitterLight {
 public:
  enum class Update { kKept, kRescaled, kSampled };
  // Traces: fills layers[(point * sampler.layerCount() + layer) * stride + k] (zeroed).
  using Sampler = std::function<void(const EmitterSampler& sampler, std::vector<float>& layers)>;

  // Makes value() the emitter light under `overrides`: kept when nothing it depends on
  // changed, rescaled when only the factors did, else sampled by `sample`. `samples` (or
  // bands) and `points` are part of what it depends on.
  Update update(const scene::Scene& scene, const rt::Accel& accel, std::span<const EmissiveOverride> overrides,
                int samples, std::size_t points, std::size_t stride, const Sampler& sample);
  // points * stride floats (zeros when nothing emits).
  std::span<const float> value() const { return value_; }
  std::span<const glm::vec3> rgb() const;  // value() as RGB, for stride 3
  std::size_t triangles() const { return triangles_; }
  int layers() const { return layout_.layers; }
  bool valid() const { return valid_; }
  void clear();

 private:
  bool valid_ = false;
  EmitterLayout layout_;
  int samples_ = 0;
  std::size_t points_ = 0, stride_ = 0, triangles_ = 0;
  std::vector<EmissiveOverride> overrides_;
  std::vector<float> layers_, value_;
};

}  // namespace lightlink::relight::detail
