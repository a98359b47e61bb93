#include "core/relight/emitter_layers.h"

#include <algorithm>

#include "core/relight/direct_points.h"

namespace lightlink::relight::detail {

EmitterLayout EmitterLayout::of(const scene::Scene& scene, std::span<const EmissiveOverride> overrides,
                                std::size_t bytes_per_layer) {
  EmitterLayout layout;
  for (const auto& o : overrides)
    if (o.mode == EmissiveOverride::Mode::kRadiance) layout.sampled.push_back({o.material, o.mode, glm::vec3(1.0f)});
  // A material emits in the layout when a static mesh of it does with unit factors.
  const std::size_t materials = scene.materials.size();
  std::vector<std::uint8_t> radiance(materials, 0), emits(materials, 0);
  for (const auto& o : layout.sampled)
    if (o.material >= 0 && std::size_t(o.material) < materials) radiance[o.material] = 1;
  bool unowned = false;  // an emitting mesh without a material cannot take a factor
  for (const auto& mesh : scene.meshes) {
    if (!mesh.is_static || mesh.triangleCount() == 0) continue;
    const bool e = (mesh.material >= 0 && radiance[mesh.material]) || scene.materialOf(mesh).isEmissive();
    if (!e) continue;
    if (mesh.material < 0) unowned = true;
    else emits[mesh.material] = 1;
  }
  std::vector<int> layer(materials, -1);
  int layers = 0;
  for (std::size_t m = 0; m < materials; ++m)
    if (emits[m]) layer[m] = layers++;
  if (unowned || layers == 0 ||
      std::size_t(layers) * bytes_per_layer > kEmitterLayerBudgetBytes) {  // one layer, the real emission
    layout.sampled.assign(overrides.begin(), overrides.end());
    return layout;
  }
  layout.layer_of_material = std::move(layer);
  layout.layers = layers;
  return layout;
}

bool EmitterLayout::sameAs(const EmitterLayout& other) const {
  return layers == other.layers && layer_of_material == other.layer_of_material && sameEmissive(sampled, other.sampled);
}

std::vector<glm::vec3> EmitterLayout::factors(std::span<const EmissiveOverride> overrides) const {
  std::vector<glm::vec3> f(std::size_t(layers), glm::vec3(1.0f));
  if (!layered()) return f;
  for (const auto& o : overrides)  // document order: a later override of a material wins
    if (o.material >= 0 && std::size_t(o.material) < layer_of_material.size() && layer_of_material[o.material] >= 0)
      f[std::size_t(layer_of_material[o.material])] = o.value;
  return f;
}

LayeredEmitterLight::Update LayeredEmitterLight::update(const scene::Scene& scene, const rt::Accel& accel,
                                                        std::span<const EmissiveOverride> overrides, int samples,
                                                        std::size_t points, std::size_t stride,
                                                        const Sampler& sample) {
  const std::vector<EmissiveOverride> now(overrides.begin(), overrides.end());
  if (valid_ && samples_ == samples && points_ == points && stride_ == stride && sameEmissive(overrides_, now))
    return Update::kKept;
  EmitterLayout layout = EmitterLayout::of(scene, overrides, points * stride * sizeof(float));
  Update how = Update::kRescaled;
  if (!(valid_ && samples_ == samples && points_ == points && stride_ == stride && layout_.sameAs(layout))) {
    const EmitterSampler sampler(scene, accel, layout.sampled, layout.layer_of_material);
    layers_.assign(points * std::size_t(sampler.layerCount()) * stride, 0.0f);
    sample(sampler, layers_);
    triangles_ = sampler.triangleCount();
    layout_ = std::move(layout);
    samples_ = samples, points_ = points, stride_ = stride;
    how = Update::kSampled;
  }
  // value = sum over layers of factor (per channel) * layer, in layer order.
  const std::vector<glm::vec3> f = layout_.factors(overrides);
  const std::size_t L = std::size_t(layout_.layers), block = stride / 3;
  value_.assign(points * stride, 0.0f);
  forChunks(points, 1024, [&](std::size_t, std::size_t begin, std::size_t end) {
    for (std::size_t c = begin; c < end; ++c) {
      float* out = value_.data() + c * stride;
      for (std::size_t l = 0; l < L; ++l) {
        const float* in = layers_.data() + (c * L + l) * stride;
        for (std::size_t k = 0; k < stride; ++k) out[k] += f[l][int(k / block)] * in[k];
      }
    }
  });
  overrides_ = now;
  valid_ = true;
  return how;
}

std::span<const glm::vec3> LayeredEmitterLight::rgb() const {
  return {reinterpret_cast<const glm::vec3*>(value_.data()), value_.size() / 3};
}

void LayeredEmitterLight::clear() {
  valid_ = false;
  layers_.clear(), value_.clear(), overrides_.clear();
  layout_ = {};
  triangles_ = 0;
}

}  // namespace lightlink::relight::detail
