// Textures -> RelightResult / GridCaches / preview caches / BakedLighting.
#include "clients/client/core_bridge.h"

#include <cmath>

namespace lightlink::client {
namespace {

std::vector<glm::vec3> toVec3(const std::vector<float>& f) {
  std::vector<glm::vec3> v(f.size() / 3);
  for (std::size_t i = 0; i < v.size(); ++i) v[i] = {f[3 * i], f[3 * i + 1], f[3 * i + 2]};
  return v;
}

Status needLightmap(const Textures& t) {
  if (!t.has(Payload::kLightmapSh) || !t.has(Payload::kLightmapValid))
    return invalidInput("result of version {} has no lightmap SH and validity (request them in the ResultSpec)",
                        t.info.version);
  return {};
}

}  // namespace

Expected<relight::RelightResult> toRelightResult(const Textures& t) {
  if (Status s = needLightmap(t); !s) return s;
  relight::RelightResult r;
  r.version = t.info.version;
  r.backend = t.info.backend;
  r.bands = t.info.bands;
  r.width = t.info.width;
  r.height = t.info.height;
  r.lightmap_sh = t.floats(Payload::kLightmapSh);
  r.direct = t.has(Payload::kLightmapDirect) ? toVec3(t.floats(Payload::kLightmapDirect))
                                             : std::vector<glm::vec3>(t.info.texels(), glm::vec3(0.0f));
  const auto valid = t.bytes(Payload::kLightmapValid);
  r.texel_valid.assign(valid.begin(), valid.end());
  if (t.has(Payload::kGridSh)) r.grid_sh = t.floats(Payload::kGridSh);
  return r;
}

Expected<caches::GridCaches> gridCachesOf(const Textures& t) {
  const ResultInfo& i = t.info;
  if (!i.has_grid || !t.has(Payload::kGridSh) || !t.has(Payload::kGridValid))
    return invalidInput("result of version {} has no grid", i.version);
  const float s = i.grid_spacing.x;
  const float tol = 1e-5f * std::max(1.0f, std::abs(s));
  if (std::abs(i.grid_spacing.y - s) > tol || std::abs(i.grid_spacing.z - s) > tol)
    return unsupported("grid spacing ({}, {}, {}) is not uniform", i.grid_spacing.x, i.grid_spacing.y,
                       i.grid_spacing.z);
  caches::GridCaches g;
  g.origin = {i.grid_origin.x, i.grid_origin.y, i.grid_origin.z};
  g.spacing_m = s;
  g.dims = {i.nx, i.ny, i.nz};
  g.position.reserve(i.gridPoints());
  for (int z = 0; z < i.nz; ++z)
    for (int y = 0; y < i.ny; ++y)
      for (int x = 0; x < i.nx; ++x) g.position.push_back(g.origin + s * glm::vec3(float(x), float(y), float(z)));
  const auto valid = t.bytes(Payload::kGridValid);
  g.valid.assign(valid.begin(), valid.end());
  return g;
}

caches::LightmapCaches previewCachesOf(const Textures& t) {
  caches::LightmapCaches c;
  c.width = t.info.width;
  c.height = t.info.height;
  const std::size_t texels = t.info.texels();
  c.cache_of_texel.assign(texels, -1);
  if (!t.has(Payload::kLightmapSh) || !t.has(Payload::kLightmapValid)) return c;
  const std::vector<float> sh = t.floats(Payload::kLightmapSh);
  const auto valid = t.bytes(Payload::kLightmapValid);
  const int nc = t.info.coeffCount();
  for (std::size_t texel = 0; texel < texels; ++texel) {
    if (!valid[texel]) continue;
    glm::vec3 n(0.0f, 0.0f, 1.0f);
    if (nc >= 4) {
      // Band 1 is (y, z, x) (docs/sh.md); sum the channels' linear terms.
      glm::vec3 d(0.0f);
      for (int ch = 0; ch < 3; ++ch) {
        const float* s = sh.data() + (texel * 3 + std::size_t(ch)) * std::size_t(nc);
        d += glm::vec3(s[3], s[1], s[2]);
      }
      const float len = glm::length(d);
      if (len > 0.0f && std::isfinite(len)) n = d / len;
    }
    c.cache_of_texel[texel] = std::int32_t(c.normal.size());
    c.normal.push_back(n);
    c.texel.push_back(std::uint32_t(texel));
  }
  return c;
}

Expected<viewer::BakedLighting> toBakedLighting(const Textures& t) {
  if (Status s = needLightmap(t); !s) return s;
  viewer::BakedLighting b;
  b.bands = t.info.bands;
  b.width = t.info.width;
  b.height = t.info.height;
  b.lightmap_sh = t.floats(Payload::kLightmapSh);
  b.direct = t.has(Payload::kLightmapDirect) ? toVec3(t.floats(Payload::kLightmapDirect))
                                             : std::vector<glm::vec3>(t.info.texels(), glm::vec3(0.0f));
  b.valid = t.floats(Payload::kLightmapValid);
  if (t.info.has_grid && t.has(Payload::kGridSh) && t.has(Payload::kGridValid)) {
    auto g = gridCachesOf(t);
    if (!g) return g.status();
    b.has_grid = true;
    b.dims = g->dims;
    b.origin = g->origin;
    b.spacing_m = g->spacing_m;
    b.grid_sh = t.floats(Payload::kGridSh);
    b.grid_bands = t.info.bands;
    b.grid_valid = t.floats(Payload::kGridValid);
  }
  return b;
}

}  // namespace lightlink::client
