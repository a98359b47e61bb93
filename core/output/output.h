// Output: what a relight hands to engines and people (DESIGN.md sec 8, docs/outputs.md).
//
//   lightmap  OpenEXR, one layer per SH coefficient `L<l><m>` with channels R, G, B
//             (m < 0 written as `m<|m|>`: L00, L1m1, L10, L11, L2m2, ...), plus `direct.{R,G,B}`
//             (baked direct irradiance; in its own file `direct` at its own size when the
//             direct layer is finer, header `lightlink.direct_scale`) and `valid.Y` (1 where
//             the texel holds a value).
//             Half by default, float on request. Row 0 = texel row 0 = glTF v = 0 (top).
//             Header attributes `lightlink.*` state the SH convention, units, bands, link form,
//             light-set version and scene hash.
//   grid      OpenEXR atlas of z-slices (slice z at x offset z * dims.x, row = y), same
//             channels minus `direct`; a JSON sidecar (origin, spacing, dims, bands, validity);
//             and a raw little-endian form for streaming (layout in docs/outputs.md).
//   preview   PNG of total irradiance (indirect SH evaluated at the cache normal + direct),
//             Reinhard tone-mapped and sRGB-encoded, for people.
//   report    JSON: the relight report plus what the writers clamped.
//
// Values beyond the half range are clamped to +-65504 in half files and counted, never
// written as infinity (DESIGN.md sec 6).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "core/caches/caches.h"
#include "core/common/status.h"
#include "core/relight/relight.h"

namespace lightlink::output {

struct ExrOptions {
  bool half = true;            // false: 32-bit float channels
  std::string scene_hash;      // e.g. the artifact cache key in hex
  std::string units = "incident radiance SH and irradiance in the units of docs/units.md (lights in cd/lux)";
};

struct WriteStats {
  std::size_t values = 0;
  std::size_t clamped = 0;  // values beyond the half range, clamped
  // Non-zero L00 / direct values below the smallest normal half (2^-14 ~ 6.1e-5): stored as
  // subnormals (absolute error up to 2^-25, relative error > 0.05 % and growing) or flushed
  // to 0. Counted so very dim lighting does not lose precision silently (DESIGN.md sec 6,
  // tests/stability); write float files (ExrOptions::half = false) or raise the exposure.
  std::size_t underflowed = 0;
};

// Channel name stem of SH coefficient i (docs/sh.md order): "L00", "L1m1", "L10", "L11", ...
std::string shLayerName(int index);

Expected<WriteStats> writeLightmapExr(const relight::RelightResult& result, const std::string& path,
                                      const ExrOptions& options = {});
// The direct layer alone (`direct.{R,G,B}`, `valid.Y`) at its own size: what bake writes as
// direct.exr when the direct layer is finer than the lightmap (lightlink.direct_scale > 1).
Expected<WriteStats> writeDirectExr(const relight::RelightResult& result, const std::string& path,
                                    const ExrOptions& options = {});
Expected<WriteStats> writeGridExr(const relight::RelightResult& result, const caches::GridCaches& grid,
                                  const std::string& path, const ExrOptions& options = {});
// JSON metadata for the grid (origin, spacing, dims, bands, channel order, validity mask).
Status writeGridJson(const relight::RelightResult& result, const caches::GridCaches& grid, const std::string& path);
// Raw little-endian: header (docs/outputs.md) + float32 SH per cache + uint8 validity.
Status writeGridRaw(const relight::RelightResult& result, const caches::GridCaches& grid, const std::string& path);

struct PreviewOptions {
  float exposure = 0.0f;  // multiplies irradiance before tone mapping; 0 = auto (mean lit texel -> 0.5)
  bool include_direct = true;
};
// With a finer direct layer, pass its texels (Precomputation::direct_texels): the preview is
// then drawn at the direct layer's size.
Status writeIrradiancePng(const relight::RelightResult& result, const caches::LightmapCaches& lightmap,
                          const std::string& path, const PreviewOptions& options = {},
                          const caches::LightmapCaches* direct_texels = nullptr);

Status writeReportJson(const nlohmann::ordered_json& report, const std::string& path);

}  // namespace lightlink::output
