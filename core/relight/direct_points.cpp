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

void footprintNeighbours(std::span<const glm::vec3> position, std::span<const float> area,
                         std::vector<std::uint32_t>& begin, std::vector<std::uint32_t>& neighbour) {
  const std::size_t n = position.size();
  begin.assign(n + 1, 0);
  neighbour.clear();
  if (n == 0) return;
  constexpr float kReach = 4.0f;
  constexpr std::size_t kMost = 24;
  std::vector<float> radius(n);
  for (std::size_t i = 0; i < n; ++i) radius[i] = std::sqrt(std::max(area[i], 0.0f) / 3.14159265f);
  std::vector<float> sorted(radius);
  std::nth_element(sorted.begin(), sorted.begin() + n / 2, sorted.end());
  const float cell = std::max(kReach * sorted[n / 2], 1e-6f);
  // Points sorted by grid cell; a cell's points are one equal range.
  auto cellOf = [&](const glm::vec3& p) { return glm::ivec3(glm::floor(p / cell)); };
  auto key = [](glm::ivec3 c) {
    return (std::uint64_t(std::uint32_t(c.x) & 0x1fffff) << 42) | (std::uint64_t(std::uint32_t(c.y) & 0x1fffff) << 21) |
           std::uint64_t(std::uint32_t(c.z) & 0x1fffff);
  };
  std::vector<std::pair<std::uint64_t, std::uint32_t>> order(n);
  for (std::size_t i = 0; i < n; ++i) order[i] = {key(cellOf(position[i])), std::uint32_t(i)};
  std::sort(order.begin(), order.end());
  std::vector<std::vector<std::uint32_t>> part((n + kChunk - 1) / kChunk);
  forChunks(n, kChunk, [&](std::size_t chunk, std::size_t b, std::size_t e) {
    std::vector<std::pair<float, std::uint32_t>> near;
    auto& out = part[chunk];
    for (std::size_t i = b; i < e; ++i) {
      const float reach = kReach * radius[i];
      const int span = int(std::ceil(reach / cell));
      const glm::ivec3 c = cellOf(position[i]);
      near.clear();
      for (int dz = -span; dz <= span; ++dz)
        for (int dy = -span; dy <= span; ++dy)
          for (int dx = -span; dx <= span; ++dx) {
            const std::uint64_t k = key(c + glm::ivec3(dx, dy, dz));
            auto lo = std::lower_bound(order.begin(), order.end(), std::make_pair(k, std::uint32_t(0)));
            for (; lo != order.end() && lo->first == k; ++lo) {
              if (lo->second == i) continue;
              const glm::vec3 d = position[lo->second] - position[i];
              const float d2 = glm::dot(d, d);
              if (d2 <= reach * reach) near.push_back({d2, lo->second});
            }
          }
      std::sort(near.begin(), near.end());
      if (near.size() > kMost) near.resize(kMost);
      out.push_back(std::uint32_t(near.size()));
      for (const auto& [d2, j] : near) out.push_back(j);
    }
  });
  std::size_t i = 0;
  for (const auto& q : part)
    for (std::size_t at = 0; at < q.size(); at += 1 + q[at], ++i) {
      begin[i + 1] = begin[i] + q[at];
      neighbour.insert(neighbour.end(), q.begin() + std::ptrdiff_t(at) + 1, q.begin() + std::ptrdiff_t(at + 1 + q[at]));
    }
}

namespace {

// The footprint's ray origins: a Vogel (golden-angle) spiral of `count` points over the disk
// of radius `radius` in the plane of nrm, turned by a per-point angle so that neighbouring
// surfels' patterns differ.
void footprintOrigins(glm::vec3 pos, glm::vec3 nrm, float radius, int count, std::uint32_t salt, glm::vec3* out) {
  glm::vec3 t, b;
  orthonormalBasis(nrm, t, b);
  constexpr float kGolden = 2.39996323f;  // pi * (3 - sqrt(5))
  const float turn = 6.28318531f * unitFloat32(mixBits32(salt ^ 0x9e3779b9U));
  for (int i = 0; i < count; ++i) {
    const float r = radius * std::sqrt((float(i) + 0.5f) / float(count));
    const float a = turn + kGolden * float(i);
    out[i] = pos + r * (std::cos(a) * t + std::sin(a) * b);
  }
}

// Where a surfel's footprint rays start, as a fraction of its disk's radius: inside, so that
// a surfel at a corner does not test from behind the neighbouring wall.
constexpr float kFootprintRadius = 0.6f;

}  // namespace

void shadowedLight(const rt::Accel& accel, const scene::Light& light, std::span<const glm::vec3> position,
                   std::span<const glm::vec3> normal, std::span<const std::uint8_t> valid,
                   const std::vector<std::uint32_t>* subset, std::vector<glm::vec3>& out, std::size_t& rays,
                   rt::Coherence coherence, Footprint footprint) {
  const std::size_t n = subset ? subset->size() : position.size();
  out.resize(position.size());
  const bool soft = footprint.rays > 1 && footprint.area.size() == position.size() &&
                    footprint.neighbour_begin.size() == position.size() + 1;
  // Per point, when soft: 0 no light, 1 centre lit, 2 centre shadowed.
  std::vector<std::uint8_t> seen_from_centre(soft ? position.size() : 0, 0);
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
    for (std::size_t k = 0; k < count; ++k) {
      if (blocked[k]) out[who[k]] = glm::vec3(0.0f);
      if (soft) seen_from_centre[who[k]] = blocked[k] ? 2 : 1;
    }
    chunk_rays[chunk] = count;
  });
  if (soft) {
    // Points near a shadow edge test their footprint (every centre is known by now).
    const int m = std::min(footprint.rays, 64);
    std::vector<std::size_t> soft_rays((n + kChunk - 1) / kChunk, 0);
    forChunks(n, kChunk, [&](std::size_t chunk, std::size_t begin, std::size_t end) {
      std::vector<rt::Ray> ray_buf;
      std::vector<std::uint8_t> blocked;
      std::vector<std::uint32_t> who;
      std::vector<glm::vec3> e_of;
      std::array<glm::vec3, 64> origin;
      for (std::size_t i = begin; i < end; ++i) {
        const std::uint32_t k = subset ? (*subset)[i] : std::uint32_t(i);
        const std::uint8_t mine = seen_from_centre[k];
        if (mine == 0) continue;
        bool edge = false;
        for (std::uint32_t a = footprint.neighbour_begin[k]; a < footprint.neighbour_begin[k + 1] && !edge; ++a) {
          const std::uint8_t theirs = seen_from_centre[footprint.neighbour[a]];
          edge = theirs != 0 && theirs != mine;
        }
        if (!edge) continue;
        const glm::vec3 pos = position[k], nrm = normal[k];
        const float radius = kFootprintRadius * std::sqrt(std::max(footprint.area[k], 0.0f) / 3.14159265f);
        footprintOrigins(pos, nrm, radius, m, k, origin.data());
        // A damaged artifact's absurd surfel area can put the footprint at infinity: such a
        // point keeps its centre ray's answer (Embree must never see a non-finite ray).
        bool finite = std::isfinite(radius);
        for (int j = 0; j < m && finite; ++j)
          finite = std::isfinite(origin[j].x) && std::isfinite(origin[j].y) && std::isfinite(origin[j].z);
        if (!finite) continue;
        for (int j = 0; j < m; ++j) ray_buf.push_back(shadowRay(accel, light, origin[j], nrm));
        who.push_back(k);
        e_of.push_back(scene::irradianceFrom(light, pos, nrm));
      }
      blocked.resize(ray_buf.size());
      accel.occluded(std::span(ray_buf.data(), ray_buf.size()), std::span(blocked.data(), blocked.size()), coherence);
      for (std::size_t w = 0; w < who.size(); ++w) {
        int visible = 0;
        for (int j = 0; j < m; ++j) visible += blocked[w * m + j] ? 0 : 1;
        out[who[w]] = e_of[w] * (float(visible) / float(m));
      }
      soft_rays[chunk] = ray_buf.size();
    });
    for (std::size_t c : soft_rays) rays += c;
  }
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
      const std::uint64_t seed = texelEmitterSeed(points.texel[c], salt);
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
      const std::uint64_t seed = gridEmitterSeed(c);
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
