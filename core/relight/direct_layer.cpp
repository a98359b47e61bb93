#include "core/relight/direct_layer.h"

#include <algorithm>
#include <chrono>

#include "core/common/sampling.h"
#include "core/relight/direct_points.h"
#include "core/relight/emitter_layers.h"
#include "core/scene/light_eval.h"

namespace lightlink::relight {

struct DirectLayer::State {
  detail::TexelMap texels;  // direct texel -> points (own point or dilation sources)
  SeamStitch seams;         // of the direct layer's atlas
  struct Kept {
    std::string id;
    scene::Light light;
    std::vector<glm::vec3> e;  // per point: this light's shadowed irradiance
  };
  std::vector<Kept> kept;  // the last call's baked lights, in its order
  detail::LayeredEmitterLight emitter;  // per point
  std::vector<glm::vec3> sum;  // per point, scratch
};

DirectLayer::DirectLayer(const scene::Scene& scene, const rt::Accel& accel, const precompute::Precomputation& p)
    : scene_(scene), accel_(accel), p_(p), s_(std::make_unique<State>()) {
  if (!active()) return;
  s_->texels = detail::buildTexelMap(p.direct_texels.cache_of_texel,
                                     detail::hasValue(p.direct_texels.valid, p.direct_fill), p.direct_dilation);
  s_->seams = SeamStitch::build(scene, p.direct_texels.width, p.direct_texels.height);
}

namespace {

// Anti-aliased shadow edges (what Bakery and Unity do with texel supersampling, here only
// where it matters): a texel whose light differs in kind (lit / unlit) from one of its 8
// neighbours is re-evaluated as the mean of 2x2 sub-texel samples on its own triangle, so a
// shadow edge becomes a ramp one texel wide instead of a staircase. Sub-samples are the
// texel's quarter points mapped through its triangle's lightmap UVs (barycentrics clamped
// into the triangle, so no sample leaves the surface); fixed, hence deterministic.
void antialiasEdges(const scene::Scene& scene, const rt::Accel& accel, const caches::LightmapCaches& dt,
                    const scene::Light& light, std::vector<glm::vec3>& e, std::size_t& rays) {
  const int w = dt.width, h = dt.height;
  const std::size_t n = dt.size();
  std::vector<std::uint32_t> edge;
  for (std::size_t c = 0; c < n; ++c) {
    if (!dt.valid[c]) continue;
    const int x = int(dt.texel[c] % std::uint32_t(w)), y = int(dt.texel[c] / std::uint32_t(w));
    const bool lit = e[c] != glm::vec3(0.0f);
    bool differs = false;
    for (int dy = -1; dy <= 1 && !differs; ++dy)
      for (int dx = -1; dx <= 1 && !differs; ++dx) {
        const int nx = x + dx, ny = y + dy;
        if ((dx == 0 && dy == 0) || nx < 0 || ny < 0 || nx >= w || ny >= h) continue;
        const std::int32_t j = dt.cache_of_texel[std::size_t(ny) * w + nx];
        differs = j >= 0 && dt.valid[std::size_t(j)] && (e[std::size_t(j)] != glm::vec3(0.0f)) != lit;
      }
    if (differs) edge.push_back(std::uint32_t(c));
  }
  std::vector<glm::vec3> value(edge.size());
  std::vector<std::size_t> chunk_rays((edge.size() + detail::kCacheChunk - 1) / detail::kCacheChunk, 0);
  detail::forChunks(edge.size(), detail::kCacheChunk, [&](std::size_t chunk, std::size_t begin, std::size_t end) {
    std::vector<rt::Ray> ray_buf;
    std::vector<glm::vec3> contrib;
    std::vector<std::uint32_t> who;
    for (std::size_t i = begin; i < end; ++i) {
      const std::uint32_t c = edge[i];
      const auto& mesh = scene.meshes[dt.mesh[c]];
      const std::size_t tri = dt.triangle[c];
      const std::uint32_t i0 = mesh.indices[3 * tri], i1 = mesh.indices[3 * tri + 1], i2 = mesh.indices[3 * tri + 2];
      const glm::vec2 scale{float(w), float(h)};
      const glm::vec2 t0 = mesh.uv1[i0] * scale, t1 = mesh.uv1[i1] * scale, t2 = mesh.uv1[i2] * scale;
      const glm::vec2 e1 = t1 - t0, e2 = t2 - t0;
      const float det = e1.x * e2.y - e1.y * e2.x;
      const float x = float(dt.texel[c] % std::uint32_t(w)), y = float(dt.texel[c] / std::uint32_t(w));
      for (int k = 0; k < 4; ++k) {
        glm::vec3 pos = dt.position[c];
        if (std::abs(det) > 1e-12f) {
          const glm::vec2 q = glm::vec2(x + 0.25f + 0.5f * float(k & 1), y + 0.25f + 0.5f * float(k >> 1)) - t0;
          float a = (q.x * e2.y - q.y * e2.x) / det, b = (e1.x * q.y - e1.y * q.x) / det;
          a = std::max(a, 0.0f), b = std::max(b, 0.0f);
          const float sum = a + b;
          if (sum > 1.0f) a /= sum, b /= sum;
          pos = mesh.positions[i0] + a * (mesh.positions[i1] - mesh.positions[i0]) +
                b * (mesh.positions[i2] - mesh.positions[i0]);
        }
        const glm::vec3 ek = detail::reaches(light, pos) ? scene::irradianceFrom(light, pos, dt.normal[c]) : glm::vec3(0.0f);
        if (ek == glm::vec3(0.0f)) continue;
        ray_buf.push_back(detail::shadowRay(accel, light, pos, dt.normal[c]));
        contrib.push_back(ek);
        who.push_back(std::uint32_t(i));
      }
    }
    std::vector<std::uint8_t> blocked(ray_buf.size());
    accel.occluded(ray_buf, blocked, rt::Coherence::kIncoherent);
    for (std::size_t i = begin; i < end; ++i) value[i] = glm::vec3(0.0f);
    for (std::size_t k = 0; k < ray_buf.size(); ++k)
      if (!blocked[k]) value[who[k]] += 0.25f * contrib[k];
    chunk_rays[chunk] = ray_buf.size();
  });
  for (std::size_t i = 0; i < edge.size(); ++i) e[edge[i]] = value[i];
  for (std::size_t r : chunk_rays) rays += r;
}

}  // namespace

DirectLayer::DirectLayer(DirectLayer&&) noexcept = default;
DirectLayer::~DirectLayer() = default;

void DirectLayer::invalidate(bool everything) {
  s_->kept.clear();
  if (everything) s_->emitter.clear();
}

void DirectLayer::compute(const LightSet& lights, const RelightOptions& o, const EffectsPlan& plan,
                          RelightResult& res) {
  const auto t0 = std::chrono::steady_clock::now();
  const caches::LightmapCaches& dt = p_.direct_texels;
  const std::size_t n = dt.size();
  State& s = *s_;

  // Punctual lights: a light equal to one kept from the last call (same id, parameters) is
  // reused, every other one traced. Kept in the new set's order, so sums run in that order.
  std::vector<State::Kept> next;
  for (const LightEntry& entry : lights.lights()) {
    if (!plan.baked_direct || !entry.baked || !detail::lightEmits(entry.light)) continue;
    auto old = std::find_if(s.kept.begin(), s.kept.end(), [&](const State::Kept& k) {
      return k.id == entry.id && sameLight(k.light, entry.light) && k.e.size() == n;
    });
    State::Kept k{entry.id, entry.light, {}};
    if (old != s.kept.end()) {
      k.e = std::move(old->e);
      s.kept.erase(old);
    } else {
      detail::shadowedLight(accel_, entry.light, dt.position, dt.normal, dt.valid, nullptr, k.e,
                            res.counts.shadow_rays, rt::Coherence::kIncoherent);
      antialiasEdges(scene_, accel_, dt, entry.light, k.e, res.counts.shadow_rays);
      res.passes.baked_direct++;
    }
    next.push_back(std::move(k));
  }
  s.kept = std::move(next);

  if (!plan.emissive_direct) {
    s.emitter.clear();
  } else {
    const auto how = s.emitter.update(scene_, accel_, lights.emissive(), o.emitter_samples, n, 3,
                                      [&](const detail::EmitterSampler& sampler, std::vector<float>& layers) {
      // Salted so the layer's texels do not repeat the caches' noise pattern.
      constexpr std::uint64_t kSalt = std::uint64_t(1) << 40;
      if (tracer_ && log_ && sampler.triangleCount() > 0) {
        std::vector<glm::vec2> rot(n);
        for (std::size_t c = 0; c < n; ++c) rot[c] = detail::emitterRotation(detail::texelEmitterSeed(dt.texel[c], kSalt));
        if (detail::traceEmitters(tracer_, sampler, {dt.position, dt.normal, dt.valid, rot}, o.emitter_samples, 0,
                                  "direct_layer_emitter", layers, res.counts.shadow_rays, *log_))
          return;
      }
      detail::sampleEmitters(sampler, dt, o.emitter_samples, kSalt, layers, res.counts.shadow_rays);
    });
    if (how == detail::LayeredEmitterLight::Update::kSampled) res.passes.emissive_direct = 1;
    else res.counts.emitter_direct_reused = 1;
    if (how == detail::LayeredEmitterLight::Update::kRescaled) res.counts.emitter_rescaled++;
    res.counts.emitter_triangles = s.emitter.triangles();
  }

  // Sum per point in light order, fill invalid points, then gather texels.
  s.sum.assign(n, glm::vec3(0.0f));
  for (const State::Kept& k : s.kept)
    for (std::size_t c = 0; c < n; ++c) s.sum[c] += k.e[c];
  if (const auto emitter = s.emitter.rgb(); emitter.size() == n)
    for (std::size_t c = 0; c < n; ++c) s.sum[c] += emitter[c];
  detail::applyFill(p_.direct_fill, reinterpret_cast<float*>(s.sum.data()), 3);
  const std::size_t texels = std::size_t(dt.width) * std::size_t(dt.height);
  res.direct_width = dt.width;
  res.direct_height = dt.height;
  res.direct.resize(texels);
  res.direct_valid.resize(texels);
  const detail::TexelMap& m = s.texels;
  detail::forChunks(texels, 4096, [&](std::size_t, std::size_t begin, std::size_t end) {
    for (std::size_t t = begin; t < end; ++t) {
      glm::vec3 e(0.0f);
      for (std::uint32_t k = m.begin[t]; k < m.begin[t + 1]; ++k) e += m.weight[k] * s.sum[m.point[k]];
      res.direct[t] = e;
      res.direct_valid[t] = m.begin[t + 1] > m.begin[t] ? 1 : 0;
    }
  });
  if (o.stitch_seams) s.seams.apply(reinterpret_cast<float*>(res.direct.data()), 3, &res.direct_seams);
  res.timings.push_back({"direct_layer", std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count()});
}

void directAtLightmapSize(const RelightResult& res, std::vector<glm::vec3>& out) {
  if (!res.directIsFiner()) {
    out = res.direct;
    return;
  }
  const int w = res.width, h = res.height, k = res.direct_width / std::max(1, w);
  out.assign(std::size_t(w) * std::size_t(h), glm::vec3(0.0f));
  if (k < 1 || res.direct_height != h * k || res.direct.size() != std::size_t(res.direct_width) * res.direct_height ||
      res.direct_valid.size() != res.direct.size())
    return;
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      glm::vec3 sum(0.0f);
      int n = 0;
      for (int j = 0; j < k; ++j)
        for (int i = 0; i < k; ++i) {
          const std::size_t t = std::size_t(y * k + j) * res.direct_width + std::size_t(x * k + i);
          if (res.direct_valid[t]) sum += res.direct[t], ++n;
        }
      if (n > 0) out[std::size_t(y) * w + x] = sum / float(n);
    }
}

}  // namespace lightlink::relight
