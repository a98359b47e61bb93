// Output: what a relight hands to engines and people (DESIGN.md sec 8, docs/outputs.md).
//
//   EXR       layout 2: single-part scanline files with plain channels, so standard readers
//             (three.js's EXRLoader, OpenEXR tools, tinyexr) load each as a texture and each
//             maps to one glTF image or KTX2 file:
//               irradiance.exr        R,G,B  the L0 map (encoding.h), every encoding
//               lightmap_<c>.exr      R,G,B  SH coefficient c (L00, L1m1, L10, L11, L2m2, ...)
//                                            of the lightmap, L1/L2 encodings only
//               direct.exr            R,G,B  baked direct irradiance (its own size when finer)
//               valid.exr             Y      1 where a lightmap texel holds a value
//               direct_valid.exr      Y      the same for a finer direct layer
//               grid_<c>.exr          R,G,B  SH coefficient c of the grid, an atlas of z-slices
//               grid_valid.exr        Y      grid validity in the same atlas
//             Half by default, float on request. Row 0 = texel row 0 = glTF v = 0 (top).
//             Header attributes `lightlink.*` state the layout version, kind, encoding, SH
//             convention, units, bands, coefficient, link form, light-set version and scene hash.
//   grid      plus a JSON sidecar (origin, spacing, dims, bands, validity, file names) and a raw
//             little-endian form for streaming (layout in docs/outputs.md).
//   preview   PNG of the irradiance of irradiance.exr, Reinhard tone-mapped and sRGB-encoded.
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
#include "core/output/encoding.h"
#include "core/relight/relight.h"

namespace lightlink::output {

// The EXR layout version every file carries in `lightlink.layout`. Layout 1 (before issue 49)
// was one multi-layer file, lightmap.exr with `L00.R`... channels, that standard readers refuse.
inline constexpr int kExrLayout = 2;

struct ExrOptions {
  bool half = true;            // false: 32-bit float channels
  Encoding encoding = Encoding::kL2;
  std::string scene_hash;      // e.g. the artifact cache key in hex
  std::string units = "incident radiance SH and irradiance in the units of docs/units.md (lights in cd/lux)";
  // false: uncompressed, for files read back at once on the same machine (the web gateway's
  // live versions), where ZIP's time to write and to inflate in a browser costs more than bytes.
  bool compress = true;
  // false: no irradiance.exr where the SH files are written (L1, L2), for readers that
  // evaluate the SH themselves (the web gateway's live versions); an L0 set always has it.
  bool irradiance = true;
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

// Name stem of SH coefficient i (docs/sh.md order): "L00", "L1m1", "L10", "L11", ...
std::string shLayerName(int index);

struct WrittenExrs {
  std::vector<std::string> files;  // file names in `dir`, in writing order
  WriteStats stats;
};
// The lightmap files of options.encoding in `dir`: irradiance.exr always (evaluateIrradiance:
// with a finer direct layer pass its texels, and irradiance.exr has the direct layer's size);
// for L1/L2 also lightmap_<c>.exr per kept coefficient, direct.exr, valid.exr and, when the
// direct layer is finer, direct_valid.exr.
Expected<WrittenExrs> writeLightmapExrs(const relight::RelightResult& result, const caches::LightmapCaches& lightmap,
                                        const std::string& dir, const ExrOptions& options = {},
                                        const caches::LightmapCaches* direct_texels = nullptr);
// grid_<c>.exr per coefficient the encoding keeps (gridBands) and grid_valid.exr in `dir`.
Expected<WrittenExrs> writeGridExrs(const relight::RelightResult& result, const caches::GridCaches& grid,
                                    const std::string& dir, const ExrOptions& options = {});
// JSON metadata for the grid (origin, spacing, dims, the bands `encoding` keeps, file names,
// validity mask).
Status writeGridJson(const relight::RelightResult& result, const caches::GridCaches& grid, const std::string& path,
                     Encoding encoding = Encoding::kL2);
// Raw little-endian: header (docs/outputs.md) + float32 SH per cache (the bands `encoding`
// keeps) + uint8 validity.
Status writeGridRaw(const relight::RelightResult& result, const caches::GridCaches& grid, const std::string& path,
                    Encoding encoding = Encoding::kL2);

struct PreviewOptions {
  float exposure = 0.0f;  // multiplies irradiance before tone mapping; 0 = auto (mean lit texel -> 0.5)
  bool include_direct = true;
};
// The image of evaluateIrradiance (with include_direct as options say). With a finer direct
// layer, pass its texels (Precomputation::direct_texels): the preview is then drawn at the
// direct layer's size.
Status writeIrradiancePng(const relight::RelightResult& result, const caches::LightmapCaches& lightmap,
                          const std::string& path, const PreviewOptions& options = {},
                          const caches::LightmapCaches* direct_texels = nullptr);

Status writeReportJson(const nlohmann::ordered_json& report, const std::string& path);

}  // namespace lightlink::output
