#include "core/output/grid_threejs.h"

#include <algorithm>
#include <bit>
#include <filesystem>
#include <fstream>

#include <nlohmann/json.hpp>

namespace lightlink::output {
namespace {

constexpr int kSubVolumes = 7;   // ceil(27 floats / 4 per texel)
constexpr int kThreeCoeffs = 9;  // L2

}  // namespace

Expected<ThreeJsGrid> threeJsGrid(const relight::RelightResult& result, const caches::GridCaches& grid) {
  const std::size_t n = grid.size();
  const int nc = result.coeffCount();
  if (n == 0 || result.grid_sh.size() != n * 3 * std::size_t(nc))
    return invalidInput("three.js grid: the result has {} grid values for {} grid caches (no grid relit?)",
                        result.grid_sh.size(), n);
  const glm::ivec3 d = grid.dims;
  if (d.x <= 0 || d.y <= 0 || d.z <= 0 || std::size_t(d.x) * d.y * d.z != n)
    return invalidInput("three.js grid: dims {}x{}x{} do not match {} caches", d.x, d.y, d.z, n);
  ThreeJsGrid out;
  out.resolution = d;
  const glm::vec3 half(0.5f * grid.spacing_m);
  out.min = grid.origin - half;
  out.max = grid.origin + grid.spacing_m * glm::vec3(d - 1) + half;
  const int padded = d.z + 2;
  out.depth = kSubVolumes * padded;
  const std::size_t slice = std::size_t(d.x) * d.y;
  out.rgba.assign(slice * out.depth * 4, 0.0f);
  const int used = std::min(nc, kThreeCoeffs);
  for (std::size_t e = 0; e < n; ++e) {
    float probe[kSubVolumes * 4] = {};
    // lightlink: R coefficients, then G, then B; three.js: coefficient-major, rgb inside.
    for (int i = 0; i < used; ++i)
      for (int ch = 0; ch < 3; ++ch) probe[i * 3 + ch] = result.grid_sh[e * 3 * nc + std::size_t(ch) * nc + i];
    const std::size_t xy = e % slice;
    const int z = int(e / slice);
    for (int t = 0; t < kSubVolumes; ++t) {
      // Data slice, plus the padding slice it is copied to when it is the first or last.
      const int base = t * padded;
      for (int s : {base + 1 + z, z == 0 ? base : -1, z == d.z - 1 ? base + padded - 1 : -1}) {
        if (s < 0) continue;
        std::copy_n(probe + t * 4, 4, out.rgba.begin() + std::ptrdiff_t((std::size_t(s) * slice + xy) * 4));
      }
    }
  }
  return out;
}

Status writeThreeJsGrid(const relight::RelightResult& result, const caches::GridCaches& grid,
                        const std::string& json_path, const std::string& bin_name) {
  static_assert(std::endian::native == std::endian::little, "three.js grid writer assumes a little-endian host");
  Expected<ThreeJsGrid> g = threeJsGrid(result, grid);
  if (!g) return g.status();
  nlohmann::ordered_json j;
  j["format"] = "lightlink.grid.threejs";
  j["format_version"] = 1;
  j["version"] = result.version;
  j["for"] = "three.js LightProbeGrid / LightProbeGridWebGL (examples/jsm/lighting, r187): Data3DTexture";
  j["min"] = {g->min.x, g->min.y, g->min.z};
  j["max"] = {g->max.x, g->max.y, g->max.z};
  j["resolution"] = {g->resolution.x, g->resolution.y, g->resolution.z};
  j["texture"] = {{"data", bin_name},
                  {"width", g->resolution.x},
                  {"height", g->resolution.y},
                  {"depth", g->depth},
                  {"format", "RGBAFormat"},
                  {"type", "FloatType"}};
  j["sh"] = "L2 radiance SH, lightlink's convention = three.js's (docs/sh.md); irradiance in lux";
  j["source_bands"] = result.bands;
  const std::filesystem::path bin_path = std::filesystem::path(json_path).parent_path() / bin_name;
  std::ofstream bin(bin_path, std::ios::binary | std::ios::trunc);
  if (!bin) return ioError("{}: cannot write the three.js grid texture", bin_path.string());
  bin.write(reinterpret_cast<const char*>(g->rgba.data()), std::streamsize(g->rgba.size() * sizeof(float)));
  if (!bin.flush()) return ioError("{}: write failed", bin_path.string());
  std::ofstream out(json_path, std::ios::binary | std::ios::trunc);
  if (!out) return ioError("{}: cannot write the three.js grid JSON", json_path);
  out << j.dump(1) << "\n";
  return out ? Status{} : ioError("{}: write failed", json_path);
}

}  // namespace lightlink::output
