// BakedLighting: what a game client has after a bake or a poll — the SH lightmap (with
// baked direct light and validity) or, for an L0 bake, the irradiance map, and the SH
// irradiance grid — read back from the files `lightlink bake` writes (EXR layout 2:
// lightmap_<c>.exr, direct.exr, valid.exr or irradiance.exr; grid.raw; docs/outputs.md), plus
// the lookups an engine does with them: bilinear texel interpolation at a lightmap UV for
// static surfaces, trilinear grid interpolation at a world position for dynamic ones. Invalid
// texels and grid points carry no weight, so an edge never blends in black.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <glm/glm.hpp>

#include "core/common/status.h"

namespace lightlink::viewer {

struct BakedLighting {
  int bands = 0;                      // lightmap SH bands; 0: an L0 bake (irradiance only)
  int width = 0, height = 0;          // lightmap texels (L0: irradiance.exr's)
  std::vector<float> lightmap_sh;     // per texel 3 * bands^2: R coefficients, then G, then B
  std::vector<float> valid;           // per texel: 1 or 0 (L0: all 1, as an engine samples it)
  std::vector<glm::vec3> irradiance;  // L0 only: per texel, direct included
  // Baked direct irradiance per direct texel: the lightmap's texels (direct_scale 1) or a
  // finer layer of the same UVs (direct.exr) with its own validity.
  int direct_scale = 1;
  int direct_width = 0, direct_height = 0;
  std::vector<glm::vec3> direct;
  std::vector<float> direct_valid;    // direct_scale > 1 only
  bool has_grid = false;
  int grid_bands = 0;
  glm::ivec3 dims{0};
  glm::vec3 origin{0.0f};
  float spacing_m = 0.0f;
  std::vector<float> grid_sh;         // per grid point, as lightmap_sh
  std::vector<float> grid_valid;

  // Indirect irradiance (SH evaluated for `normal`) + baked direct at lightmap UV `uv`; for an
  // L0 bake the irradiance map's value (baked for the surface's normal). Returns false when no
  // valid texel surrounds uv.
  bool sampleLightmap(glm::vec2 uv, const glm::vec3& normal, glm::vec3& irradiance) const;
  // Indirect irradiance from the grid at world position p for `normal`.
  bool sampleGrid(const glm::vec3& p, const glm::vec3& normal, glm::vec3& irradiance) const;
};

// Reads the lightmap files of a bake in `dir` — the SH set (lightmap_L00.exr and the other
// coefficients, direct.exr, valid.exr, direct_valid.exr when the direct layer is finer) or,
// for an L0 bake, irradiance.exr — and, when present, grid.raw, and checks that they agree
// (sizes, bands). A layout-1 bake (lightmap.exr) is refused with a message to rebake. Nothing
// read is trusted: see the readers below.
Expected<BakedLighting> loadBakedLighting(const std::string& dir);

// The largest lightmap read (16384^2 texels, the largest atlas `unwrap` makes).
inline constexpr std::uint64_t kMaxLightmapTexels = std::uint64_t(16384) * 16384;
// The largest grid read, in points.
inline constexpr std::uint64_t kMaxGridPoints = std::uint64_t(1) << 24;

// One lightlink EXR of layout 2 (core/output/output.h), as read.
struct ExrImage {
  std::string kind;      // lightlink.kind: irradiance, lightmap_sh, direct, valid, ...
  int bands = 0;         // lightlink.bands
  int sh_index = -1;     // lightlink.sh_index of a *_sh file
  int direct_scale = 1;  // lightlink.direct_scale
  int width = 0, height = 0;
  int channels = 0;           // 3 (R, G, B) or 1 (Y)
  std::vector<float> values;  // per texel `channels` floats, row 0 first
};
// Reads one file. Rejects, naming what is wrong: not an OpenEXR file, a tiled, multi-part or
// deep file, a missing lightlink.layout (a layout-1 lightmap: rebake) or a layout other than
// output::kExrLayout, a missing or unknown lightlink.kind, bands out of 0..4, a coefficient
// out of range, channels other than the kind's (R,G,B or Y), a data window that is empty or
// larger than `max_texels`, a value that is not finite.
Status readLightlinkExr(const std::string& path, ExrImage& out, std::uint64_t max_texels = kMaxLightmapTexels);
// Reads the SH set of a bake in `dir` (see loadBakedLighting) into b's lightmap fields.
Status readLightmapExrs(const std::string& dir, BakedLighting& b, std::uint64_t max_texels = kMaxLightmapTexels);
// Reads an irradiance.exr into b as an L0 lightmap (bands 0).
Status readIrradianceExr(const std::string& path, BakedLighting& b, std::uint64_t max_texels = kMaxLightmapTexels);

// Reads a grid.raw (docs/outputs.md) into b's grid fields. Every header field is checked
// before anything is allocated: bands 1..4, each dim 1..2^24 and their product at most
// kMaxGridPoints (no overflow), a finite origin, a finite positive spacing, and a file
// length equal to what bands and dims imply; then every SH value must be finite and every
// validity byte 0 or 1. Sets b.grid_bands (loadBakedLighting checks it against the lightmap's).
Status readGridRaw(const std::string& path, BakedLighting& b);

}  // namespace lightlink::viewer
