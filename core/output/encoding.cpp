#include "core/output/encoding.h"

#include <algorithm>
#include <cmath>

#include "core/sh/sh.h"

namespace lightlink::output {
namespace {

// How far (in texels) dilated texels of the irradiance image are filled from evaluated ones;
// the relight's own dilation reaches a few texels into the gutter.
constexpr int kMaxDilationPasses = 16;

}  // namespace
std::vector<float> truncateSh(const std::vector<float>& sh, int from_bands, int to_bands) {
  const std::size_t from = std::size_t(from_bands) * from_bands, to = std::size_t(to_bands) * to_bands;
  if (from == 0 || to >= from) return sh;
  const std::size_t elements = sh.size() / (3 * from);
  std::vector<float> out(elements * 3 * to);
  for (std::size_t e = 0; e < elements; ++e)
    for (std::size_t ch = 0; ch < 3; ++ch)
      std::copy_n(sh.data() + e * 3 * from + ch * from, to, out.data() + e * 3 * to + ch * to);
  return out;
}

Expected<Encoding> parseEncoding(std::string_view name) {
  if (name == "l0") return Encoding::kL0;
  if (name == "l1") return Encoding::kL1;
  if (name == "l2") return Encoding::kL2;
  return invalidInput("--encoding '{}' is not one of l0 (RGB irradiance), l1 (4 SH coefficients), l2 (9)", name);
}

std::string_view encodingName(Encoding e) {
  switch (e) {
    case Encoding::kL0: return "l0";
    case Encoding::kL1: return "l1";
    case Encoding::kL2: return "l2";
  }
  return "l2";
}

int lightmapBands(Encoding e, int result_bands) {
  switch (e) {
    case Encoding::kL0: return 0;
    case Encoding::kL1: return std::min(2, result_bands);
    case Encoding::kL2: return result_bands;
  }
  return result_bands;
}

int gridBands(Encoding e, int result_bands) { return std::max(std::min(1, result_bands), lightmapBands(e, result_bands)); }

Expected<IrradianceImage> evaluateIrradiance(const relight::RelightResult& result,
                                             const caches::LightmapCaches& lightmap, bool include_direct,
                                             const caches::LightmapCaches* direct_texels) {
  const int w = result.width, h = result.height;
  const std::size_t texels = std::size_t(w) * h;
  const int nc = result.coeffCount();
  if (texels == 0 || lightmap.cache_of_texel.size() != texels || result.lightmap_sh.size() != texels * 3 * nc)
    return invalidInput("irradiance: result and lightmap caches disagree ({}x{})", w, h);
  const bool fine = result.directIsFiner() && direct_texels != nullptr && direct_texels->width == result.direct_width &&
                    direct_texels->height == result.direct_height &&
                    result.direct.size() == std::size_t(result.direct_width) * result.direct_height;
  if (!fine && result.directIsFiner() && include_direct)
    return invalidInput("irradiance: a {}x{} direct layer needs its texels", result.direct_width, result.direct_height);
  IrradianceImage img;
  img.width = fine ? result.direct_width : w;
  img.height = fine ? result.direct_height : h;
  const int ow = img.width, oh = img.height;
  const std::size_t out_texels = std::size_t(ow) * oh;
  img.irradiance.assign(out_texels, glm::vec3(0.0f));
  img.lit.assign(out_texels, 0);
  std::vector<float> sh(3 * std::size_t(nc));
  for (std::size_t t = 0; t < out_texels; ++t) {
    glm::vec3 nrm;
    if (fine) {
      const std::int32_t c = direct_texels->cache_of_texel[t];
      if (c < 0 || !result.direct_valid[t]) continue;
      nrm = direct_texels->normal[c];
      const float fx = (float(t % ow) + 0.5f) * float(w) / float(ow) - 0.5f;
      const float fy = (float(t / ow) + 0.5f) * float(h) / float(oh) - 0.5f;
      const int x0 = int(std::floor(fx)), y0 = int(std::floor(fy));
      std::fill(sh.begin(), sh.end(), 0.0f);
      float wsum = 0.0f;
      for (int dy = 0; dy < 2; ++dy)
        for (int dx = 0; dx < 2; ++dx) {
          const int x = std::clamp(x0 + dx, 0, w - 1), y = std::clamp(y0 + dy, 0, h - 1);
          const std::size_t s = std::size_t(y) * w + x;
          const float wt = (dx ? fx - float(x0) : 1.0f - (fx - float(x0))) * (dy ? fy - float(y0) : 1.0f - (fy - float(y0)));
          if (!result.texel_valid[s] || wt <= 0.0f) continue;
          for (int k = 0; k < 3 * nc; ++k) sh[k] += wt * result.lightmap_sh[s * 3 * nc + k];
          wsum += wt;
        }
      if (wsum > 0.0f)
        for (float& v : sh) v /= wsum;
    } else {
      const std::int32_t c = lightmap.cache_of_texel[t];
      if (c < 0 || !result.texel_valid[t]) continue;
      nrm = lightmap.normal[c];
      std::copy_n(result.lightmap_sh.data() + t * 3 * nc, 3 * nc, sh.data());
    }
    img.irradiance[t] = glm::vec3(sh::irradiance(result.bands, sh.data(), nrm),
                                  sh::irradiance(result.bands, sh.data() + nc, nrm),
                                  sh::irradiance(result.bands, sh.data() + 2 * nc, nrm));
    if (include_direct) img.irradiance[t] += result.direct[t];
    img.lit[t] = 1;
  }
  // Texels the relight filled by dilation (valid, but no cache: no normal of their own) take
  // the mean of their evaluated 8-neighbours, pass by pass outwards, as the relight's dilation
  // spread the SH and direct values: bilinear sampling at a chart's edge then never blends in
  // the black of an empty texel.
  const std::vector<std::uint8_t>& holds = fine ? result.direct_valid : result.texel_valid;
  std::vector<std::size_t> filled;
  for (int pass = 0; pass < kMaxDilationPasses; ++pass) {
    filled.clear();
    for (std::size_t t = 0; t < out_texels; ++t) {
      if (img.lit[t] || !holds[t]) continue;
      const int x = int(t % ow), y = int(t / ow);
      glm::vec3 sum(0.0f);
      int n = 0;
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) {
          const int nx = x + dx, ny = y + dy;
          if (nx < 0 || ny < 0 || nx >= ow || ny >= oh) continue;
          const std::size_t s = std::size_t(ny) * ow + nx;
          if (img.lit[s]) sum += img.irradiance[s], ++n;
        }
      if (n > 0) {
        img.irradiance[t] = sum / float(n);
        filled.push_back(t);
      }
    }
    if (filled.empty()) break;
    for (std::size_t t : filled) img.lit[t] = 1;  // after the pass: the result does not depend on the scan order
  }
  return img;
}

}  // namespace lightlink::output
