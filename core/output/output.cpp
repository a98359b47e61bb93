#include "core/output/output.h"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>
#include <filesystem>
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

// What a file's header says besides the common attributes.
struct FileTags {
  std::string kind;      // irradiance, lightmap_sh, direct, valid, direct_valid, grid_sh, grid_valid
  int bands = 0;         // SH bands of the set the file belongs to (0: the L0 irradiance)
  int sh_index = -1;     // SH coefficient of a *_sh file
};

Expected<WriteStats> writeExr(Planes& planes, const std::string& path, const relight::RelightResult& result,
                              const ExrOptions& options, const FileTags& tags) {
  try {
    Imf::Header header(planes.width, planes.height);
    header.compression() = options.compress ? Imf::ZIP_COMPRESSION : Imf::NO_COMPRESSION;
    const Imf::PixelType type = planes.half ? Imf::HALF : Imf::FLOAT;
    Imf::FrameBuffer fb;
    const std::size_t elem = planes.half ? sizeof(half_bits) : sizeof(float);
    for (std::size_t c = 0; c < planes.names.size(); ++c) {
      header.channels().insert(planes.names[c], Imf::Channel(type));
      char* base = planes.half ? reinterpret_cast<char*>(planes.h[c].data()) : reinterpret_cast<char*>(planes.f[c].data());
      fb.insert(planes.names[c], Imf::Slice(type, base, elem, elem * planes.width));
    }
    header.insert("lightlink.layout", Imf::IntAttribute(kExrLayout));
    header.insert("lightlink.kind", Imf::StringAttribute(tags.kind));
    header.insert("lightlink.encoding", Imf::StringAttribute(std::string(encodingName(options.encoding))));
    header.insert("lightlink.sh_convention", Imf::StringAttribute(kShConvention));
    header.insert("lightlink.units", Imf::StringAttribute(options.units));
    header.insert("lightlink.bands", Imf::IntAttribute(tags.bands));
    if (tags.sh_index >= 0) {
      header.insert("lightlink.sh_index", Imf::IntAttribute(tags.sh_index));
      header.insert("lightlink.sh_name", Imf::StringAttribute(shLayerName(tags.sh_index)));
    }
    header.insert("lightlink.version", Imf::StringAttribute(std::to_string(result.version)));
    header.insert("lightlink.scene_hash", Imf::StringAttribute(options.scene_hash));
    header.insert("lightlink.link_form",
                  Imf::StringAttribute(std::string(relight::linkFormName(result.link_form))));
    // How many direct texels per lightmap texel (1: direct.exr has the lightmap's size).
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

void addStats(WriteStats& to, const WriteStats& from) {
  to.values += from.values;
  to.clamped += from.clamped;
  to.underflowed += from.underflowed;
}

// One file per SH coefficient of `sh` (laid out per element as [R coeffs][G coeffs][B coeffs]
// with nc coefficients, of which the first `keep` are written), named <prefix>_<coef>.exr;
// element e goes to pixel pixel_of(e).
template <typename PixelOf>
Status writeShFiles(const std::vector<float>& sh, std::size_t elements, int nc, int keep_bands, int width, int height,
                    PixelOf pixel_of, const std::string& dir, const std::string& prefix,
                    const relight::RelightResult& result, const ExrOptions& options, WrittenExrs& written) {
  const std::size_t pixels = std::size_t(width) * height;
  static const char* kCh[3] = {"R", "G", "B"};
  std::vector<float> plane(pixels);
  for (int i = 0; i < keep_bands * keep_bands; ++i) {
    Planes planes{width, height, options.half};
    for (int ch = 0; ch < 3; ++ch) {
      std::fill(plane.begin(), plane.end(), 0.0f);
      for (std::size_t e = 0; e < elements; ++e) plane[pixel_of(e)] = sh[e * 3 * nc + ch * nc + i];
      planes.add(kCh[ch], plane, /*signal=*/i == 0);
    }
    const std::string name = prefix + "_" + shLayerName(i) + ".exr";
    auto s = writeExr(planes, (std::filesystem::path(dir) / name).string(), result, options,
                      {prefix + "_sh", keep_bands, i});
    if (!s) return s.status();
    addStats(written.stats, *s);
    written.files.push_back(name);
  }
  return {};
}

// A one-channel `Y` file of 0/1 validity.
Status writeValidFile(const std::vector<float>& plane, int width, int height, const std::string& dir,
                      const std::string& name, const std::string& kind, int bands,
                      const relight::RelightResult& result, const ExrOptions& options, WrittenExrs& written) {
  Planes planes{width, height, options.half};
  planes.add("Y", plane);
  auto s = writeExr(planes, (std::filesystem::path(dir) / name).string(), result, options, {kind, bands});
  if (!s) return s.status();
  addStats(written.stats, *s);
  written.files.push_back(name);
  return {};
}

// An R,G,B file of per-texel vec3 values.
Status writeRgbFile(const std::vector<glm::vec3>& values, int width, int height, const std::string& dir,
                    const std::string& name, const std::string& kind, int bands,
                    const relight::RelightResult& result, const ExrOptions& options, WrittenExrs& written) {
  Planes planes{width, height, options.half};
  std::vector<float> plane(values.size());
  static const char* kCh[3] = {"R", "G", "B"};
  for (int ch = 0; ch < 3; ++ch) {
    for (std::size_t t = 0; t < values.size(); ++t) plane[t] = values[t][ch];
    planes.add(kCh[ch], plane, /*signal=*/true);
  }
  auto s = writeExr(planes, (std::filesystem::path(dir) / name).string(), result, options, {kind, bands});
  if (!s) return s.status();
  addStats(written.stats, *s);
  written.files.push_back(name);
  return {};
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

Expected<WrittenExrs> writeLightmapExrs(const relight::RelightResult& result, const caches::LightmapCaches& lightmap,
                                        const std::string& dir, const ExrOptions& options,
                                        const caches::LightmapCaches* direct_texels) {
  const std::size_t texels = std::size_t(result.width) * result.height;
  const int nc = result.coeffCount();
  const bool finer = result.directIsFiner();
  if (texels == 0 || result.lightmap_sh.size() != texels * 3 * nc || (!finer && result.direct.size() != texels) ||
      result.texel_valid.size() != texels)
    return invalidInput("lightmap EXR: result holds no {}x{} lightmap", result.width, result.height);
  WrittenExrs written;
  const int bands = lightmapBands(options.encoding, result.bands);
  if (options.irradiance || bands == 0) {
    auto irradiance = evaluateIrradiance(result, lightmap, /*include_direct=*/true, direct_texels);
    if (!irradiance) return irradiance.status();
    if (Status s = writeRgbFile(irradiance->irradiance, irradiance->width, irradiance->height, dir, "irradiance.exr",
                                "irradiance", 0, result, options, written);
        !s)
      return s;
  }
  if (bands == 0) return written;
  if (Status s = writeShFiles(result.lightmap_sh, texels, nc, bands, result.width, result.height,
                              [](std::size_t t) { return t; }, dir, "lightmap", result, options, written);
      !s)
    return s;
  if (Status s = writeRgbFile(result.direct, finer ? result.direct_width : result.width,
                              finer ? result.direct_height : result.height, dir, "direct.exr", "direct", bands, result,
                              options, written);
      !s)
    return s;
  std::vector<float> plane(texels);
  for (std::size_t t = 0; t < texels; ++t) plane[t] = result.texel_valid[t] ? 1.0f : 0.0f;
  if (Status s = writeValidFile(plane, result.width, result.height, dir, "valid.exr", "valid", bands, result, options,
                                written);
      !s)
    return s;
  if (finer) {
    const std::size_t dt = std::size_t(result.direct_width) * result.direct_height;
    if (result.direct_valid.size() != dt)
      return invalidInput("lightmap EXR: the {}x{} direct layer has no validity", result.direct_width,
                          result.direct_height);
    plane.assign(dt, 0.0f);
    for (std::size_t t = 0; t < dt; ++t) plane[t] = result.direct_valid[t] ? 1.0f : 0.0f;
    if (Status s = writeValidFile(plane, result.direct_width, result.direct_height, dir, "direct_valid.exr",
                                  "direct_valid", bands, result, options, written);
        !s)
      return s;
  }
  return written;
}

Expected<WrittenExrs> writeGridExrs(const relight::RelightResult& result, const caches::GridCaches& grid,
                                    const std::string& dir, const ExrOptions& options) {
  if (Status s = checkGrid(result, grid); !s) return s;
  const glm::ivec3 d = grid.dims;
  // Cache index (z * dims.y + y) * dims.x + x -> pixel (z * dims.x + x, y).
  auto pixel_of = [&](std::size_t e) {
    const std::size_t x = e % d.x, y = (e / d.x) % d.y, z = e / (std::size_t(d.x) * d.y);
    return y * std::size_t(d.x) * d.z + z * d.x + x;
  };
  WrittenExrs written;
  const int bands = gridBands(options.encoding, result.bands);
  if (Status s = writeShFiles(result.grid_sh, grid.size(), result.coeffCount(), bands, d.x * d.z, d.y, pixel_of, dir,
                              "grid", result, options, written);
      !s)
    return s;
  std::vector<float> plane(grid.size());
  for (std::size_t e = 0; e < grid.size(); ++e) plane[pixel_of(e)] = grid.valid[e] ? 1.0f : 0.0f;
  if (Status s = writeValidFile(plane, d.x * d.z, d.y, dir, "grid_valid.exr", "grid_valid", bands, result, options,
                                written);
      !s)
    return s;
  return written;
}

Status writeGridJson(const relight::RelightResult& result, const caches::GridCaches& grid, const std::string& path,
                     Encoding encoding) {
  if (Status s = checkGrid(result, grid); !s) return s;
  const int bands = gridBands(encoding, result.bands);
  nlohmann::ordered_json j;
  j["format"] = "lightlink.grid";
  j["format_version"] = 2;
  j["version"] = result.version;
  j["encoding"] = encodingName(encoding);
  j["bands"] = bands;
  j["origin_m"] = {grid.origin.x, grid.origin.y, grid.origin.z};
  j["spacing_m"] = grid.spacing_m;
  j["dims"] = {grid.dims.x, grid.dims.y, grid.dims.z};
  j["index"] = "(z * dims[1] + y) * dims[0] + x; world = origin_m + spacing_m * (x, y, z)";
  j["exr_atlas"] = "slice z at pixel x offset z * dims[0], pixel row = y";
  j["exr_layout"] = kExrLayout;
  std::vector<std::string> files;
  for (int i = 0; i < bands * bands; ++i) files.push_back("grid_" + shLayerName(i) + ".exr");
  j["sh_files"] = files;
  j["valid_file"] = "grid_valid.exr";
  j["valid"] = grid.valid;
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  if (!out) return ioError("{}: cannot write grid JSON", path);
  out << j.dump(1) << "\n";
  return out ? Status{} : ioError("{}: write failed", path);
}

Status writeGridRaw(const relight::RelightResult& result, const caches::GridCaches& grid, const std::string& path,
                    Encoding encoding) {
  if (Status s = checkGrid(result, grid); !s) return s;
  const int bands = gridBands(encoding, result.bands);
  const std::vector<float> sh = truncateSh(result.grid_sh, result.bands, bands);
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  if (!out) return ioError("{}: cannot write raw grid", path);
  out.write("LLGRID01", 8);
  putLe<std::uint64_t>(out, result.version);
  putLe<std::uint32_t>(out, std::uint32_t(bands));
  for (int a = 0; a < 3; ++a) putLe<std::uint32_t>(out, std::uint32_t(grid.dims[a]));
  for (int a = 0; a < 3; ++a) putLe<float>(out, grid.origin[a]);
  putLe<float>(out, grid.spacing_m);
  out.write(reinterpret_cast<const char*>(sh.data()), std::streamsize(sh.size() * sizeof(float)));
  out.write(reinterpret_cast<const char*>(grid.valid.data()), std::streamsize(grid.valid.size()));
  return out ? Status{} : ioError("{}: write failed", path);
}

Status writeIrradiancePng(const relight::RelightResult& result, const caches::LightmapCaches& lightmap,
                          const std::string& path, const PreviewOptions& options,
                          const caches::LightmapCaches* direct_texels) {
  auto img = evaluateIrradiance(result, lightmap, options.include_direct, direct_texels);
  if (!img) return img.status();
  const int ow = img->width, oh = img->height;
  const std::size_t out_texels = std::size_t(ow) * oh;
  const std::vector<glm::vec3>& e = img->irradiance;
  const std::vector<std::uint8_t>& lit = img->lit;
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
