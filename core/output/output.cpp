#include "core/output/output.h"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>
#include <fstream>

#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfIntAttribute.h>
#include <OpenEXR/ImfOutputFile.h>
#include <OpenEXR/ImfStringAttribute.h>

#include "core/common/half.h"
#include "core/common/png.h"
#include "core/sh/sh.h"

namespace lightlink::output {
namespace {

constexpr const char* kShConvention =
    "real orthonormal SH, no Condon-Shortley phase, index l*l+l+m, plain radiance projection "
    "(constant L: L00 = L*sqrt(4pi)); irradiance = sum A_l L_lm Y_lm(n), A = {pi, 2pi/3, pi/4, 0} (docs/sh.md)";

// One image worth of named planar channels, converted to the file's pixel type up front.
struct Planes {
  int width = 0, height = 0;
  bool half = true;
  std::vector<std::string> names;
  std::vector<std::vector<half_bits>> h;
  std::vector<std::vector<float>> f;
  WriteStats stats;

  // `signal`: the plane carries a texel's magnitude (L00, direct), so a non-zero value below
  // the smallest normal half is a real loss of precision and is counted; higher SH
  // coefficients are legitimately tiny next to their L00 and are not.
  void add(const std::string& name, const std::vector<float>& values, bool signal = false) {
    constexpr float kHalfMinNormal = 6.103515625e-05f;  // 2^-14
    names.push_back(name);
    if (half) {
      std::vector<half_bits> out(values.size());
      for (std::size_t i = 0; i < values.size(); ++i) {
        bool clamped = false;
        out[i] = toHalfSaturating(values[i], clamped);
        stats.clamped += clamped;
        stats.underflowed += signal && values[i] != 0.0f && std::abs(values[i]) < kHalfMinNormal;
      }
      h.push_back(std::move(out));
    } else {
      f.push_back(values);
    }
    stats.values += values.size();
  }
};

Expected<WriteStats> writeExr(Planes& planes, const std::string& path, const relight::RelightResult& result,
                              const ExrOptions& options, const std::string& kind) {
  try {
    Imf::Header header(planes.width, planes.height);
    header.compression() = Imf::ZIP_COMPRESSION;
    const Imf::PixelType type = planes.half ? Imf::HALF : Imf::FLOAT;
    Imf::FrameBuffer fb;
    const std::size_t elem = planes.half ? sizeof(half_bits) : sizeof(float);
    for (std::size_t c = 0; c < planes.names.size(); ++c) {
      header.channels().insert(planes.names[c], Imf::Channel(type));
      char* base = planes.half ? reinterpret_cast<char*>(planes.h[c].data()) : reinterpret_cast<char*>(planes.f[c].data());
      fb.insert(planes.names[c], Imf::Slice(type, base, elem, elem * planes.width));
    }
    header.insert("lightlink.kind", Imf::StringAttribute(kind));
    header.insert("lightlink.sh_convention", Imf::StringAttribute(kShConvention));
    header.insert("lightlink.units", Imf::StringAttribute(options.units));
    header.insert("lightlink.bands", Imf::IntAttribute(result.bands));
    header.insert("lightlink.version", Imf::StringAttribute(std::to_string(result.version)));
    header.insert("lightlink.scene_hash", Imf::StringAttribute(options.scene_hash));
    header.insert("lightlink.link_form",
                  Imf::StringAttribute(std::string(relight::linkFormName(result.link_form))));
    // How many direct texels per lightmap texel (1: `direct` is in the lightmap file itself).
    if (result.width > 0)
      header.insert("lightlink.direct_scale", Imf::IntAttribute(std::max(1, result.direct_width / result.width)));
    Imf::OutputFile file(path.c_str(), header);
    file.setFrameBuffer(fb);
    file.writePixels(planes.height);
  } catch (const std::exception& e) {
    return ioError("{}: cannot write EXR: {}", path, e.what());
  }
  return planes.stats;
}

// Channel planes of SH data laid out per element as [R coeffs][G coeffs][B coeffs]; element
// e goes to pixel pixel_of(e).
template <typename PixelOf>
void addShPlanes(Planes& planes, const std::vector<float>& sh, std::size_t elements, int nc, PixelOf pixel_of) {
  const std::size_t pixels = std::size_t(planes.width) * planes.height;
  static const char* kCh[3] = {"R", "G", "B"};
  std::vector<float> plane(pixels);
  for (int i = 0; i < nc; ++i)
    for (int ch = 0; ch < 3; ++ch) {
      std::fill(plane.begin(), plane.end(), 0.0f);
      for (std::size_t e = 0; e < elements; ++e) plane[pixel_of(e)] = sh[e * 3 * nc + ch * nc + i];
      planes.add(shLayerName(i) + "." + kCh[ch], plane, /*signal=*/i == 0);
    }
}

template <typename T>
void putLe(std::ofstream& out, T v) {
  static_assert(std::endian::native == std::endian::little, "raw grid writer assumes a little-endian host");
  out.write(reinterpret_cast<const char*>(&v), sizeof(T));
}

Status checkGrid(const relight::RelightResult& r, const caches::GridCaches& grid) {
  const std::size_t n = grid.size();
  if (n == 0 || r.grid_sh.size() != n * 3 * std::size_t(r.coeffCount()))
    return invalidInput("grid output: the result has {} grid values for {} grid caches (no grid relit?)",
                        r.grid_sh.size(), n);
  if (std::size_t(grid.dims.x) * grid.dims.y * grid.dims.z != n)
    return invalidInput("grid output: dims {}x{}x{} do not match {} caches", grid.dims.x, grid.dims.y, grid.dims.z, n);
  return {};
}

}  // namespace

std::string shLayerName(int index) {
  const int l = sh::bandOf(index);
  const int m = index - l * l - l;
  return m < 0 ? fmt::format("L{}m{}", l, -m) : fmt::format("L{}{}", l, m);
}

Expected<WriteStats> writeLightmapExr(const relight::RelightResult& result, const std::string& path,
                                      const ExrOptions& options) {
  const std::size_t texels = std::size_t(result.width) * result.height;
  const int nc = result.coeffCount();
  const bool finer = result.directIsFiner();
  if (texels == 0 || result.lightmap_sh.size() != texels * 3 * nc || (!finer && result.direct.size() != texels))
    return invalidInput("lightmap EXR: result holds no {}x{} lightmap", result.width, result.height);
  Planes planes{result.width, result.height, options.half};
  addShPlanes(planes, result.lightmap_sh, texels, nc, [](std::size_t t) { return t; });
  std::vector<float> plane(texels);
  static const char* kCh[3] = {"R", "G", "B"};
  // A finer direct layer goes to its own file (writeDirectExr); the header says its scale.
  for (int ch = 0; ch < 3 && !finer; ++ch) {
    for (std::size_t t = 0; t < texels; ++t) plane[t] = result.direct[t][ch];
    planes.add(std::string("direct.") + kCh[ch], plane, /*signal=*/true);
  }
  for (std::size_t t = 0; t < texels; ++t) plane[t] = result.texel_valid[t] ? 1.0f : 0.0f;
  planes.add("valid.Y", plane);
  return writeExr(planes, path, result, options, "lightmap");
}

Expected<WriteStats> writeDirectExr(const relight::RelightResult& result, const std::string& path,
                                    const ExrOptions& options) {
  const std::size_t texels = std::size_t(result.direct_width) * std::size_t(result.direct_height);
  const bool finer = result.directIsFiner();
  const std::vector<std::uint8_t>& valid = finer ? result.direct_valid : result.texel_valid;
  if (texels == 0 || result.direct.size() != texels || valid.size() != texels)
    return invalidInput("direct EXR: result holds no {}x{} direct layer", result.direct_width, result.direct_height);
  Planes planes{result.direct_width, result.direct_height, options.half};
  std::vector<float> plane(texels);
  static const char* kCh[3] = {"R", "G", "B"};
  for (int ch = 0; ch < 3; ++ch) {
    for (std::size_t t = 0; t < texels; ++t) plane[t] = result.direct[t][ch];
    planes.add(std::string("direct.") + kCh[ch], plane, /*signal=*/true);
  }
  for (std::size_t t = 0; t < texels; ++t) plane[t] = valid[t] ? 1.0f : 0.0f;
  planes.add("valid.Y", plane);
  return writeExr(planes, path, result, options, "direct");
}

Expected<WriteStats> writeGridExr(const relight::RelightResult& result, const caches::GridCaches& grid,
                                  const std::string& path, const ExrOptions& options) {
  if (Status s = checkGrid(result, grid); !s) return s;
  const glm::ivec3 d = grid.dims;
  Planes planes{d.x * d.z, d.y, options.half};
  // Cache index (z * dims.y + y) * dims.x + x -> pixel (z * dims.x + x, y).
  auto pixel_of = [&](std::size_t e) {
    const std::size_t x = e % d.x, y = (e / d.x) % d.y, z = e / (std::size_t(d.x) * d.y);
    return y * std::size_t(d.x) * d.z + z * d.x + x;
  };
  addShPlanes(planes, result.grid_sh, grid.size(), result.coeffCount(), pixel_of);
  std::vector<float> plane(grid.size());
  for (std::size_t e = 0; e < grid.size(); ++e) plane[pixel_of(e)] = grid.valid[e] ? 1.0f : 0.0f;
  planes.add("valid.Y", plane);
  return writeExr(planes, path, result, options, "grid");
}

Status writeGridJson(const relight::RelightResult& result, const caches::GridCaches& grid, const std::string& path) {
  if (Status s = checkGrid(result, grid); !s) return s;
  nlohmann::ordered_json j;
  j["format"] = "lightlink.grid";
  j["format_version"] = 1;
  j["version"] = result.version;
  j["bands"] = result.bands;
  j["origin_m"] = {grid.origin.x, grid.origin.y, grid.origin.z};
  j["spacing_m"] = grid.spacing_m;
  j["dims"] = {grid.dims.x, grid.dims.y, grid.dims.z};
  j["index"] = "(z * dims[1] + y) * dims[0] + x; world = origin_m + spacing_m * (x, y, z)";
  j["exr_atlas"] = "slice z at pixel x offset z * dims[0], pixel row = y";
  std::vector<std::string> layers;
  for (int i = 0; i < result.coeffCount(); ++i) layers.push_back(shLayerName(i));
  j["sh_layers"] = layers;
  j["valid"] = grid.valid;
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  if (!out) return ioError("{}: cannot write grid JSON", path);
  out << j.dump(1) << "\n";
  return out ? Status{} : ioError("{}: write failed", path);
}

Status writeGridRaw(const relight::RelightResult& result, const caches::GridCaches& grid, const std::string& path) {
  if (Status s = checkGrid(result, grid); !s) return s;
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  if (!out) return ioError("{}: cannot write raw grid", path);
  out.write("LLGRID01", 8);
  putLe<std::uint64_t>(out, result.version);
  putLe<std::uint32_t>(out, std::uint32_t(result.bands));
  for (int a = 0; a < 3; ++a) putLe<std::uint32_t>(out, std::uint32_t(grid.dims[a]));
  for (int a = 0; a < 3; ++a) putLe<float>(out, grid.origin[a]);
  putLe<float>(out, grid.spacing_m);
  out.write(reinterpret_cast<const char*>(result.grid_sh.data()), std::streamsize(result.grid_sh.size() * sizeof(float)));
  out.write(reinterpret_cast<const char*>(grid.valid.data()), std::streamsize(grid.valid.size()));
  return out ? Status{} : ioError("{}: write failed", path);
}

Status writeIrradiancePng(const relight::RelightResult& result, const caches::LightmapCaches& lightmap,
                          const std::string& path, const PreviewOptions& options,
                          const caches::LightmapCaches* direct_texels) {
  const int w = result.width, h = result.height;
  const std::size_t texels = std::size_t(w) * h;
  const int nc = result.coeffCount();
  if (texels == 0 || lightmap.cache_of_texel.size() != texels || result.lightmap_sh.size() != texels * 3 * nc)
    return invalidInput("irradiance preview: result and lightmap caches disagree ({}x{})", w, h);
  // With a finer direct layer (and its texels) the preview is drawn at the direct layer's
  // size: the indirect SH interpolated bilinearly over valid lightmap texels, evaluated at the
  // direct texel's own normal, plus its direct light. Otherwise texel by texel.
  const bool fine = result.directIsFiner() && direct_texels != nullptr && direct_texels->width == result.direct_width &&
                    direct_texels->height == result.direct_height &&
                    result.direct.size() == std::size_t(result.direct_width) * result.direct_height;
  const int ow = fine ? result.direct_width : w, oh = fine ? result.direct_height : h;
  const std::size_t out_texels = std::size_t(ow) * oh;
  if (!fine && result.directIsFiner() && options.include_direct)
    return invalidInput("irradiance preview: a {}x{} direct layer needs its texels", result.direct_width,
                        result.direct_height);
  std::vector<glm::vec3> e(out_texels, glm::vec3(0.0f));
  std::vector<std::uint8_t> lit(out_texels, 0);
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
    e[t] = glm::vec3(sh::irradiance(result.bands, sh.data(), nrm), sh::irradiance(result.bands, sh.data() + nc, nrm),
                     sh::irradiance(result.bands, sh.data() + 2 * nc, nrm));
    if (options.include_direct) e[t] += result.direct[t];
    lit[t] = 1;
  }
  double sum = 0.0;
  std::size_t n = 0;
  for (std::size_t t = 0; t < out_texels; ++t)
    if (lit[t]) sum += (e[t].x + e[t].y + e[t].z) / 3.0, ++n;
  const float exposure = options.exposure > 0.0f ? options.exposure : (sum > 0.0 ? float(n / sum) : 1.0f);
  std::vector<std::uint8_t> rgb(out_texels * 3, 0);
  for (std::size_t t = 0; t < out_texels; ++t) {
    if (!lit[t]) {
      rgb[3 * t] = rgb[3 * t + 1] = rgb[3 * t + 2] = 24;  // empty texels dark grey, not black
      continue;
    }
    for (int ch = 0; ch < 3; ++ch) {
      const float x = e[t][ch] * exposure;
      rgb[3 * t + ch] = encodeSrgb8(x / (1.0f + x));  // Reinhard
    }
  }
  return writePngRgb8(path, ow, oh, rgb, "irradiance preview");
}

Status writeReportJson(const nlohmann::ordered_json& report, const std::string& path) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  if (!out) return ioError("{}: cannot write report", path);
  out << report.dump(2) << "\n";
  return out ? Status{} : ioError("{}: write failed", path);
}

}  // namespace lightlink::output
