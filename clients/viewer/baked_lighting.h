// BakedLighting: what a game client has after a bake or a poll — the SH lightmap (with
// baked direct light and validity) and the SH irradiance grid — read back from the files
// `lightlink bake` writes (lightmap.exr, grid.raw; docs/outputs.md), plus the lookups an
// engine does with them: bilinear texel interpolation at a lightmap UV for static surfaces,
// trilinear grid interpolation at a world position for dynamic ones. Invalid texels and
// grid points carry no weight, so an edge never blends in black.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <glm/glm.hpp>

#include "core/common/status.h"

namespace lightlink::viewer {

struct BakedLighting {
  int bands = 0;
  int width = 0, height = 0;          // lightmap texels
  std::vector<float> lightmap_sh;     // per texel 3 * bands^2: R coefficients, then G, then B
  std::vector<float> valid;           // per texel: 1 or 0
  // Baked direct irradiance per direct texel: the lightmap's texels (direct_scale 1) or a
  // finer layer of the same UVs (direct.exr) with its own validity.
  int direct_scale = 1;
  int direct_width = 0, direct_height = 0;
  std::vector<glm::vec3> direct;
  std::vector<float> direct_valid;    // direct_scale > 1 only
  bool has_grid = false;
  glm::ivec3 dims{0};
  glm::vec3 origin{0.0f};
  float spacing_m = 0.0f;
  std::vector<float> grid_sh;         // per grid point, as lightmap_sh
  std::vector<float> grid_valid;

  // Indirect irradiance (SH evaluated for `normal`) + baked direct at lightmap UV `uv`.
  // Returns false when no valid texel surrounds uv.
  bool sampleLightmap(glm::vec2 uv, const glm::vec3& normal, glm::vec3& irradiance) const;
  // Indirect irradiance from the grid at world position p for `normal`.
  bool sampleGrid(const glm::vec3& p, const glm::vec3& normal, glm::vec3& irradiance) const;
};

// Reads `dir`/lightmap.exr, `dir`/direct.exr when the lightmap says its direct layer is
// finer, and, when present, `dir`/grid.raw, and checks that they agree (same bands, sizes). Nothing read is trusted: see the two readers below.
Expected<BakedLighting> loadBakedLighting(const std::string& dir);

// The largest lightmap read (16384^2 texels, the largest atlas `unwrap` makes).
inline constexpr std::uint64_t kMaxLightmapTexels = std::uint64_t(16384) * 16384;
// The largest grid read, in points.
inline constexpr std::uint64_t kMaxGridPoints = std::uint64_t(1) << 24;

// Reads a lightmap EXR into b's lightmap fields (bands, size, SH, direct, valid). Rejects,
// naming what is wrong: a missing or out-of-range lightlink.bands, a missing channel, a data
// window that is empty or larger than `max_texels`, a value that is not finite.
Status readLightmapExr(const std::string& path, BakedLighting& b, std::uint64_t max_texels = kMaxLightmapTexels);
// Reads a direct.exr (the finer direct layer; its size must be the lightmap's times the
// lightmap's lightlink.direct_scale) into b's direct fields. Call after readLightmapExr.
Status readDirectExr(const std::string& path, BakedLighting& b, std::uint64_t max_texels = kMaxLightmapTexels);

// Reads a grid.raw (docs/outputs.md) into b's grid fields. Every header field is checked
// before anything is allocated: bands 1..4, each dim 1..2^24 and their product at most
// kMaxGridPoints (no overflow), a finite origin, a finite positive spacing, and a file
// length equal to what bands and dims imply; then every SH value must be finite and every
// validity byte 0 or 1. When b.bands is set (a lightmap was read first) the grid's bands
// must equal it; otherwise b.bands takes the grid's.
Status readGridRaw(const std::string& path, BakedLighting& b);

}  // namespace lightlink::viewer
