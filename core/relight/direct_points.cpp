#include "core/relight/direct_points.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <utility>

#include "core/common/sampling.h"
#include "core/scene/light_eval.h"

namespace lightlink::relight::detail {

bool sameEmissive(const std::vector<EmissiveOverride>& a, const std::vector<EmissiveOverride>& b) {
  if (a.size() != b.size()) return false;
  for (std::size_t i = 0; i < a.size(); ++i)
    if (a[i].material != b[i].material || a[i].mode != b[i].mode || a[i].value != b[i].value) return false;
  return true;
}

bool lightEmits(const scene::Light& l) {
  return l.intensity > 0.0f && (l.color.x > 0.0f || l.color.y > 0.0f || l.color.z > 0.0f);
}

bool reaches(const scene::Light& l, const glm::vec3& p) {
  if (!lightEmits(l)) return false;
  if (l.kind == scene::Light::Kind::kDirectional) return true;
  const glm::vec3 d = p - l.position;
  const float dist2 = glm::dot(d, d);
  if (l.range > 0.0f && dist2 >= l.range * l.range) return false;
  if (l.kind == scene::Light::Kind::kSpot) {
    if (dist2 <= 0.0f) return false;
    return glm::dot(d, l.direction) > std::cos(l.outer_cone_angle) * std::sqrt(dist2);
  }
  return true;
}

rt::Ray shadowRay(const rt::Accel& accel, const scene::Light& light, glm::vec3 pos, glm::vec3 nrm) {
  rt::Ray ray;
  if (light.kind == scene::Light::Kind::kDirectional) {
    ray.dir = -light.direction;
    ray.origin = accel.offsetOrigin(pos, nrm, ray.dir);
  } else {
    ray.origin = accel.offsetOrigin(pos, nrm, light.position - pos);
    ray.dir = light.position - ray.origin;
    // Stop short of the light by the ray epsilon (a light on a surface is not shadowed
    // by that surface); t is in units of |dir|.
    ray.tfar = std::max(0.0f, 1.0f - accel.rayEpsilon() / std::max(glm::length(ray.dir), 1e-30f));
  }
  return ray;
}

void shadowedLight(const rt::Accel& accel, const scene::Light& light, std::span<const glm::vec3> position,
                   std::span<const glm::vec3> normal, std::span<const std::uint8_t> valid,
                   const std::vector<std::uint32_t>* subset, std::vector<glm::vec3>& out, std::size_t& rays,
                   rt::Coherence coherence) {
  const std::size_t n = subset ? subset->size() : position.size();
  out.resize(position.size());
  std::vector<std::size_t> chunk_rays((n + kChunk - 1) / kChunk, 0);
  forChunks(n, kChunk, [&](std::size_t chunk, std::size_t begin, std::size_t end) {
    std::array<rt::Ray, kChunk> ray_buf;
    std::array<std::uint32_t, kChunk> who;
    std::array<std::uint8_t, kChunk> blocked;
    std::size_t count = 0;
    for (std::size_t i = begin; i < end; ++i) {
      const std::uint32_t k = subset ? (*subset)[i] : std::uint32_t(i);
      const glm::vec3 pos = position[k], nrm = normal[k];
      const bool lit = (valid.empty() || valid[k]) && reaches(light, pos);
      const glm::vec3 e = lit ? scene::irradianceFrom(light, pos, nrm) : glm::vec3(0.0f);
      out[k] = e;
      if (e == glm::vec3(0.0f)) continue;
      const rt::Ray ray = shadowRay(accel, light, pos, nrm);
      ray_buf[count] = ray;
      who[count++] = k;
    }
    accel.occluded(std::span(ray_buf.data(), count), std::span(blocked.data(), count), coherence);
    for (std::size_t k = 0; k < count; ++k)
      if (blocked[k]) out[who[k]] = glm::vec3(0.0f);
    chunk_rays[chunk] = count;
  });
  for (std::size_t c : chunk_rays) rays += c;
}


void sampleEmitters(const EmitterSampler& sampler, const caches::LightmapCaches& points, int samples,
                    std::uint64_t salt, std::vector<float>& layers, std::size_t& rays) {
  const std::size_t n = points.size(), L = std::size_t(sampler.layerCount());
  layers.assign(n * L * 3, 0.0f);
  std::vector<std::size_t> chunk_rays((n + kCacheChunk - 1) / kCacheChunk, 0);
  forChunks(n, kCacheChunk, [&](std::size_t chunk, std::size_t begin, std::size_t end) {
    EmitterSampler::Scratch scratch;
    std::size_t r = 0;
    for (std::size_t c = begin; c < end; ++c) {
      if (!points.valid[c]) continue;
      const std::uint64_t seed = mixBits(0x6c6c656d69747465ULL ^ (std::uint64_t(points.texel[c]) | salt));
      sampler.irradiance(points.position[c], points.normal[c], samples, seed, scratch,
                         reinterpret_cast<glm::vec3*>(layers.data() + c * L * 3), r);
    }
    chunk_rays[chunk] = r;
  });
  for (std::size_t r : chunk_rays) rays += r;
}

void sampleEmittersSh(const EmitterSampler& sampler, const caches::GridCaches& grid, int bands, int samples,
                      std::vector<float>& layers, std::size_t& rays) {
  const std::size_t n = grid.size(), stride = std::size_t(3) * bands * bands, L = std::size_t(sampler.layerCount());
  layers.assign(n * L * stride, 0.0f);
  std::vector<std::size_t> chunk_rays((n + kCacheChunk - 1) / kCacheChunk, 0);
  forChunks(n, kCacheChunk, [&](std::size_t chunk, std::size_t begin, std::size_t end) {
    EmitterSampler::Scratch scratch;
    std::size_t r = 0;
    for (std::size_t c = begin; c < end; ++c) {
      if (!grid.valid[c]) continue;
      const std::uint64_t seed = mixBits(0x67726964656d6974ULL ^ std::uint64_t(c));
      sampler.radianceSh(grid.position[c], bands, samples, seed, scratch, layers.data() + c * L * stride, r);
    }
    chunk_rays[chunk] = r;
  });
  for (std::size_t r : chunk_rays) rays += r;
}

std::vector<std::uint8_t> hasValue(const std::vector<std::uint8_t>& valid, const caches::FillPlan& fill) {
  std::vector<std::uint8_t> v(valid);
  for (std::size_t t = 0; t < fill.target.size(); ++t)
    if (fill.source_begin[t + 1] > fill.source_begin[t]) v[fill.target[t]] = 1;
  return v;
}

void applyFill(const caches::FillPlan& plan, float* data, std::size_t stride) {
  for (std::size_t t = 0; t < plan.target.size(); ++t) {
    const std::uint32_t b0i = plan.source_begin[t], b1i = plan.source_begin[t + 1];
    float* dst = data + std::size_t(plan.target[t]) * stride;
    std::fill(dst, dst + stride, 0.0f);
    if (b1i == b0i) continue;
    const float inv = 1.0f / float(b1i - b0i);
    for (std::uint32_t k = b0i; k < b1i; ++k) {
      const float* src = data + std::size_t(plan.source[k]) * stride;
      for (std::size_t i = 0; i < stride; ++i) dst[i] += src[i];
    }
    for (std::size_t i = 0; i < stride; ++i) dst[i] *= inv;
  }
}

TexelMap buildTexelMap(const std::vector<std::int32_t>& cot, const std::vector<std::uint8_t>& has_value,
                       const caches::FillPlan& d) {
  const std::size_t texels = cot.size();
  // Dilated texels' point weights, built in plan order exactly as a per-relight dilation
  // would average them: a source counts when it holds a value at that point of the plan.
  using Entry = std::pair<std::uint32_t, float>;
  std::vector<std::int32_t> dilated(texels, -1);
  std::vector<std::vector<Entry>> lists;
  std::vector<Entry> acc;
  for (std::size_t t = 0; t < d.target.size(); ++t) {
    acc.clear();
    std::uint32_t used = 0;
    for (std::uint32_t k = d.source_begin[t]; k < d.source_begin[t + 1]; ++k) {
      const std::uint32_t src = d.source[k];
      const std::int32_t c = src < cot.size() ? cot[src] : -1;
      if (c >= 0 && has_value[std::size_t(c)]) {
        acc.emplace_back(std::uint32_t(c), 1.0f);
        ++used;
      } else if (dilated[src] >= 0) {
        for (const Entry& e : lists[std::size_t(dilated[src])]) acc.push_back(e);
        ++used;
      }
    }
    if (used == 0) continue;
    std::sort(acc.begin(), acc.end(), [](const Entry& a, const Entry& b) { return a.first < b.first; });
    std::vector<Entry> merged;
    for (const Entry& e : acc) {
      if (!merged.empty() && merged.back().first == e.first) merged.back().second += e.second;
      else merged.push_back(e);
    }
    const float inv = 1.0f / float(used);
    for (Entry& e : merged) e.second *= inv;
    dilated[d.target[t]] = std::int32_t(lists.size());
    lists.push_back(std::move(merged));
  }
  TexelMap m;
  m.begin.assign(texels + 1, 0);
  for (std::size_t t = 0; t < texels; ++t) {
    std::size_t n = 0;
    if (cot[t] >= 0 && has_value[std::size_t(cot[t])]) n = 1;
    else if (dilated[t] >= 0) n = lists[std::size_t(dilated[t])].size();
    m.begin[t + 1] = m.begin[t] + std::uint32_t(n);
  }
  m.point.resize(m.begin[texels]);
  m.weight.resize(m.begin[texels]);
  for (std::size_t t = 0; t < texels; ++t) {
    std::uint32_t k = m.begin[t];
    if (cot[t] >= 0 && has_value[std::size_t(cot[t])]) {
      m.point[k] = std::uint32_t(cot[t]);
      m.weight[k] = 1.0f;
    } else if (dilated[t] >= 0) {
      for (const Entry& e : lists[std::size_t(dilated[t])]) m.point[k] = e.first, m.weight[k++] = e.second;
    }
  }
  return m;
}

}  // namespace lightlink::relight::detail
