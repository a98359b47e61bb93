#include "core/relight/indirect_smooth.h"

#include <cmath>
#include <cstring>

#include <glm/glm.hpp>

#include "core/relight/direct_points.h"

namespace lightlink::relight::detail {

IndirectSmooth IndirectSmooth::build(const caches::LightmapCaches& lm, const std::vector<std::uint8_t>& has_value) {
  IndirectSmooth out;
  const int w = lm.width, h = lm.height;
  out.texels_ = std::size_t(w) * h;
  out.begin_.push_back(0);
  struct Src {
    std::uint32_t texel;
    int dx, dy;
  };
  std::vector<Src> src;
  for (std::size_t c = 0; c < lm.size(); ++c) {
    if (!has_value[c]) continue;
    const std::uint32_t t = lm.texel[c];
    const int tx = int(t % std::uint32_t(w)), ty = int(t / std::uint32_t(w));
    const glm::vec3 p = lm.position[c], n = lm.normal[c];
    src.clear();
    float nearest = INFINITY;  // distance to the closest edge neighbour on the plane
    for (int pass = 0; pass < 2; ++pass)
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) {
          const bool edge = (dx == 0) != (dy == 0);
          if ((pass == 0) != edge) continue;  // edge neighbours first: they set `nearest`
          const int x = tx + dx, y = ty + dy;
          if (x < 0 || y < 0 || x >= w || y >= h) continue;
          const std::uint32_t t2 = std::uint32_t(y * w + x);
          if (dx == 0 && dy == 0) {
            src.push_back({t2, 0, 0});
            continue;
          }
          const std::int32_t c2 = lm.cache_of_texel[t2];
          if (c2 < 0 || !has_value[std::size_t(c2)] || lm.texel[std::size_t(c2)] != t2 ||
              lm.mesh[std::size_t(c2)] != lm.mesh[c])
            continue;
          // Same plane of the same mesh (a chart is one mesh's; gutters separate charts): close
          // normals, the offset in the plane, a corner no farther than its edges allow.
          const glm::vec3 d = lm.position[std::size_t(c2)] - p;
          const float len = glm::length(d);
          if (glm::dot(n, lm.normal[std::size_t(c2)]) < 0.9f || std::abs(glm::dot(d, n)) > 0.25f * len) continue;
          if (edge) nearest = std::min(nearest, len);
          else if (!(nearest < INFINITY && len <= 2.5f * nearest)) continue;
          src.push_back({t2, dx, dy});
        }
    // Keep the centre and the neighbours whose mirror image is kept too: a symmetric stencil's
    // mean is exact for a linear trend (the first-order terms cancel), as a one-sided one is
    // not at a chart border, and its weights are positive (no overshoot, no negative light).
    bool have[3][3] = {};
    for (const Src& q : src) have[q.dy + 1][q.dx + 1] = true;
    std::size_t kept = 0;
    for (const Src& q : src) kept += have[1 - q.dy][1 - q.dx];
    if (kept < 3) continue;  // the centre alone: left as is
    out.target_.push_back(t);
    for (const Src& q : src)
      if (have[1 - q.dy][1 - q.dx]) out.source_.push_back(q.texel), out.weight_.push_back(1.0f / float(kept));
    out.begin_.push_back(std::uint32_t(out.source_.size()));
  }
  return out;
}

void IndirectSmooth::apply(float* data, std::size_t stride, std::vector<float>& scratch) const {
  if (target_.empty()) return;
  scratch.assign(data, data + texels_ * stride);
  forChunks(target_.size(), 4096, [&](std::size_t, std::size_t b, std::size_t e) {
    for (std::size_t i = b; i < e; ++i) {
      float* dst = data + std::size_t(target_[i]) * stride;
      std::memset(dst, 0, stride * sizeof(float));
      for (std::uint32_t k = begin_[i]; k < begin_[i + 1]; ++k) {
        const float* s = scratch.data() + std::size_t(source_[k]) * stride;
        const float wk = weight_[k];
        for (std::size_t j = 0; j < stride; ++j) dst[j] += wk * s[j];
      }
    }
  });
}

}  // namespace lightlink::relight::detail
