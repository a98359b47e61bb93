#include "clients/viewer/baked_lighting.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <optional>

#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfInputFile.h>
#include <OpenEXR/ImfIntAttribute.h>
#include <OpenEXR/ImfStringAttribute.h>

#include "core/output/output.h"
#include "core/sh/sh.h"

namespace lightlink::viewer {
namespace {

// SH irradiance of one point's 3 planar channels for `normal`.
glm::vec3 shIrradiance(const float* sh, int bands, const glm::vec3& normal) {
  const int nc = bands * bands;
  return {sh::irradiance(bands, sh, normal), sh::irradiance(bands, sh + nc, normal),
          sh::irradiance(bands, sh + 2 * nc, normal)};
}

// Reads `n` bytes at the current position; false when the file ends first.
bool readExactly(std::ifstream& in, void* dst, std::size_t n) {
  in.read(static_cast<char*>(dst), static_cast<std::streamsize>(n));
  return in && static_cast<std::size_t>(in.gcount()) == n;
}

// Opens a regular file (a FIFO or a directory would block or fail mid-read) and returns its size.
Expected<std::uint64_t> regularFileSize(const std::string& path) {
  std::error_code ec;
  const auto st = std::filesystem::status(path, ec);
  if (ec || !std::filesystem::exists(st)) return ioError("cannot open {}", path);
  if (!std::filesystem::is_regular_file(st)) return invalidInput("{} is not a regular file", path);
  const std::uintmax_t size = std::filesystem::file_size(path, ec);
  if (ec) return ioError("cannot read the size of {}", path);
  return std::uint64_t(size);
}

// Walks the EXR header (magic, version, then name\0 type\0 int32 size value...) as OpenEXR
// parses it, before OpenEXR does: OpenEXR allocates an attribute's stated size before it
// reads it, so a 5 KB file could make it allocate 2 GB. Only the attribute types a lightmap
// uses are accepted, each value must have exactly its stated size (OpenEXR parses typed
// values by their content, so a size that disagrees would desynchronise this walk), and
// every size must fit in the file.
Status checkExrHeader(const std::string& path, std::uint64_t file_bytes) {
  std::ifstream in(path, std::ios::binary);
  std::vector<char> head(static_cast<std::size_t>(std::min<std::uint64_t>(file_bytes, 1 << 20)));
  if (!readExactly(in, head.data(), head.size())) return ioError("cannot read {}", path);
  const auto u32 = [&](std::size_t at) {
    std::uint32_t v;
    std::memcpy(&v, head.data() + at, 4);
    return v;
  };
  if (head.size() < 8 || u32(0) != 20000630u) return invalidInput("{} is not an OpenEXR file (bad magic)", path);
  const std::uint32_t flags = u32(4);
  if (flags & 0x1a00u) return invalidInput("{}: a tiled, multi-part or deep EXR is not a lightlink lightmap", path);
  const std::size_t max_name = (flags & 0x400u) ? 255 : 31;
  const auto bad = [&](std::size_t at, const char* what) {
    return invalidInput("{}: malformed EXR header at byte {} ({})", path, at, what);
  };
  // A null-terminated name of at most max_name characters at `at`; npos when there is none.
  const auto name_at = [&](std::size_t at, std::string& out) {
    const auto begin = head.begin() + std::ptrdiff_t(at);
    const auto end = std::find(begin, std::min(head.end(), begin + std::ptrdiff_t(max_name) + 1), '\0');
    if (end == head.end() || end == begin + std::ptrdiff_t(max_name) + 1) return std::string::npos;
    out.assign(begin, end);
    return at + out.size() + 1;
  };
  // Fixed-size attribute types a lightlink lightmap (or a standard EXR header) holds.
  const auto fixed_size = [](const std::string& type) -> int {
    if (type == "box2i" || type == "box2f") return 16;
    if (type == "int" || type == "float") return 4;
    if (type == "v2f" || type == "v2i") return 8;
    if (type == "v3f" || type == "v3i") return 12;
    if (type == "compression" || type == "lineOrder" || type == "envmap") return 1;
    if (type == "chromaticities") return 32;
    return -1;
  };
  std::size_t at = 8;
  std::string name, type, channel;
  for (;;) {
    if (at >= head.size()) return bad(at, "the header does not end");
    if (head[at] == '\0') return {};  // the empty name ends the header
    const std::size_t type_at = name_at(at, name);
    if (type_at == std::string::npos) return bad(at, "attribute name");
    const std::size_t size_at = name_at(type_at, type);
    if (size_at == std::string::npos || size_at + 4 > head.size()) return bad(type_at, "attribute type");
    const std::uint32_t size = u32(size_at);
    const std::size_t value_at = size_at + 4;
    if (size > file_bytes - value_at)
      return invalidInput("{}: header attribute '{}' claims {} bytes, beyond the end of the file", path, name, size);
    if (value_at + size > head.size()) return bad(value_at, "the header does not end");
    if (type == "chlist") {  // channels: name\0 + 16 bytes each, until an empty name
      std::size_t c = value_at;
      while (c < value_at + size && head[c] != '\0') {
        const std::size_t next = name_at(c, channel);
        if (next == std::string::npos) return bad(c, "channel name");
        c = next + 16;
      }
      if (c + 1 != value_at + size) return bad(value_at, "the channel list disagrees with its size");
    } else if (type != "string" && fixed_size(type) != static_cast<int>(size)) {
      return invalidInput("{}: header attribute '{}' of type '{}' ({} bytes) is not one a lightlink lightmap holds",
                          path, name.substr(0, 64), type.substr(0, 64), size);
    }
    at = value_at + size;
  }
}

bool finite3(const float v[3]) { return std::isfinite(v[0]) && std::isfinite(v[1]) && std::isfinite(v[2]); }

}  // namespace

namespace {

// The channels each kind of file holds.
int channelsOfKind(const std::string& kind) {
  if (kind == "irradiance" || kind == "lightmap_sh" || kind == "direct" || kind == "grid_sh") return 3;
  if (kind == "valid" || kind == "direct_valid" || kind == "grid_valid") return 1;
  return 0;
}

}  // namespace

Status readLightlinkExr(const std::string& path, ExrImage& out, std::uint64_t max_texels) {
  auto file_bytes = regularFileSize(path);
  if (!file_bytes) return file_bytes.status();
  if (Status s = checkExrHeader(path, *file_bytes); !s) return s;
  try {
    // OpenEXR sizes its line buffers and offset tables from the header: refuse absurd
    // windows before it does. The limits are process-wide (they also bind writers), so they
    // are lifted again once the header is read.
    struct ExrLimits {
      ExrLimits() {
        Imf::Header::setMaxImageSize(16384, 16384);
        Imf::Header::setMaxTileSize(16384, 16384);
      }
      ~ExrLimits() {
        Imf::Header::setMaxImageSize(0, 0);  // 0: OpenEXR's default, no limit
        Imf::Header::setMaxTileSize(0, 0);
      }
    };
    std::optional<ExrLimits> limits(std::in_place);
    Imf::InputFile file(path.c_str());
    limits.reset();
    const Imf::Header& h = file.header();
    const auto* layout = h.findTypedAttribute<Imf::IntAttribute>("lightlink.layout");
    if (layout == nullptr) {
      if (h.findTypedAttribute<Imf::IntAttribute>("lightlink.bands") != nullptr)
        return invalidInput("{} is a lightlink EXR of layout 1 (one file of L00.R, ... layers), which this lightlink "
                            "no longer reads: bake again to write layout {}",
                            path, output::kExrLayout);
      return invalidInput("{} is not a lightlink EXR (no lightlink.layout attribute)", path);
    }
    if (layout->value() != output::kExrLayout)
      return invalidInput("{}: lightlink.layout {} is not the layout this lightlink reads ({})", path, layout->value(),
                          output::kExrLayout);
    const auto* kind = h.findTypedAttribute<Imf::StringAttribute>("lightlink.kind");
    const int channels = kind ? channelsOfKind(kind->value()) : 0;
    if (channels == 0)
      return invalidInput("{}: lightlink.kind '{}' is not one this lightlink reads", path,
                          kind ? kind->value().substr(0, 64) : std::string("(missing)"));
    const auto* bands = h.findTypedAttribute<Imf::IntAttribute>("lightlink.bands");
    if (bands == nullptr || bands->value() < 0 || bands->value() > 4)
      return invalidInput("{}: lightlink.bands is missing or out of range (0..4)", path);
    const bool sh_file = kind->value() == "lightmap_sh" || kind->value() == "grid_sh";
    const auto* index = h.findTypedAttribute<Imf::IntAttribute>("lightlink.sh_index");
    if (sh_file && (index == nullptr || index->value() < 0 || index->value() >= bands->value() * bands->value()))
      return invalidInput("{}: lightlink.sh_index is missing or out of range for {} bands", path, bands->value());
    const auto* scale = h.findTypedAttribute<Imf::IntAttribute>("lightlink.direct_scale");
    const int direct_scale = scale ? scale->value() : 1;
    if (direct_scale < 1 || direct_scale > 64)
      return invalidInput("{}: lightlink.direct_scale {} is out of range (1..64)", path, direct_scale);
    const Imath::Box2i dw = h.dataWindow();
    const std::int64_t w = std::int64_t(dw.max.x) - dw.min.x + 1, hgt = std::int64_t(dw.max.y) - dw.min.y + 1;
    // Each side bounded first: the product of two 2^32 sides would wrap.
    if (w < 1 || hgt < 1 || std::uint64_t(w) > max_texels || std::uint64_t(hgt) > max_texels ||
        std::uint64_t(w) * std::uint64_t(hgt) > max_texels)
      return invalidInput("{}: data window {}x{} is out of range (1 to {} texels)", path, w, hgt, max_texels);
    static const char* kRgb[3] = {"R", "G", "B"};
    const std::vector<const char*> names = channels == 3 ? std::vector<const char*>{kRgb[0], kRgb[1], kRgb[2]}
                                                         : std::vector<const char*>{"Y"};
    std::size_t present = 0;
    for (auto it = h.channels().begin(); it != h.channels().end(); ++it) ++present;
    if (present != names.size())
      return invalidInput("{}: a '{}' file holds the channels {}, but this one has {} channels", path, kind->value(),
                          channels == 3 ? "R, G, B" : "Y", present);
    const std::size_t texels = std::size_t(w) * std::size_t(hgt);
    std::vector<float> values(texels * std::size_t(channels), 0.0f);
    const std::ptrdiff_t origin = std::ptrdiff_t(dw.min.x) + std::ptrdiff_t(dw.min.y) * std::ptrdiff_t(w);
    const std::size_t xs = sizeof(float) * std::size_t(channels);
    Imf::FrameBuffer fb;
    for (int c = 0; c < channels; ++c) {
      if (h.channels().findChannel(names[std::size_t(c)]) == nullptr)
        return invalidInput("{}: channel {} is missing", path, names[std::size_t(c)]);
      char* base = reinterpret_cast<char*>(values.data() + c) - origin * std::ptrdiff_t(xs);
      fb.insert(names[std::size_t(c)], Imf::Slice(Imf::FLOAT, base, xs, xs * std::size_t(w)));
    }
    file.setFrameBuffer(fb);
    file.readPixels(dw.min.y, dw.max.y);
    for (std::size_t k = 0; k < values.size(); ++k)
      if (!std::isfinite(values[k]))
        return invalidInput("{}: channel {} of texel ({}, {}) is not finite", path, names[k % std::size_t(channels)],
                            (k / std::size_t(channels)) % std::size_t(w), (k / std::size_t(channels)) / std::size_t(w));
    out.kind = kind->value();
    out.bands = bands->value();
    out.sh_index = sh_file ? index->value() : -1;
    out.direct_scale = direct_scale;
    out.width = static_cast<int>(w);
    out.height = static_cast<int>(hgt);
    out.channels = channels;
    out.values = std::move(values);
  } catch (const std::exception& e) {
    return invalidInput("cannot read lightmap {}: {}", path, e.what());
  }
  return {};
}

namespace {

// Reads `path` and checks it is a `kind` file of w x h texels (w = 0: any size).
Expected<ExrImage> readKind(const std::string& path, const std::string& kind, int w, int h, std::uint64_t max_texels) {
  ExrImage img;
  if (Status s = readLightlinkExr(path, img, max_texels); !s) return s;
  if (img.kind != kind) return invalidInput("{}: lightlink.kind is '{}', expected '{}'", path, img.kind, kind);
  if (w > 0 && (img.width != w || img.height != h))
    return invalidInput("{}: {}x{} texels, but the lightmap has {}x{}", path, img.width, img.height, w, h);
  return img;
}

std::vector<glm::vec3> toVec3(const std::vector<float>& rgb) {
  std::vector<glm::vec3> out(rgb.size() / 3);
  for (std::size_t t = 0; t < out.size(); ++t) out[t] = glm::vec3(rgb[3 * t], rgb[3 * t + 1], rgb[3 * t + 2]);
  return out;
}

}  // namespace

Status readLightmapExrs(const std::string& dir, BakedLighting& b, std::uint64_t max_texels) {
  const std::filesystem::path d(dir);
  auto first = readKind((d / "lightmap_L00.exr").string(), "lightmap_sh", 0, 0, max_texels);
  if (!first) return first.status();
  if (first->bands < 1) return invalidInput("{}: lightlink.bands is 0 in an SH file", (d / "lightmap_L00.exr").string());
  const int w = first->width, h = first->height, bands = first->bands, nc = bands * bands;
  const std::size_t texels = std::size_t(w) * std::size_t(h);
  b.bands = bands;
  b.width = w;
  b.height = h;
  b.direct_scale = first->direct_scale;
  b.irradiance.clear();
  b.lightmap_sh.assign(texels * 3 * std::size_t(nc), 0.0f);
  for (int i = 0; i < nc; ++i) {
    const std::string path = (d / ("lightmap_" + output::shLayerName(i) + ".exr")).string();
    Expected<ExrImage> img = i == 0 ? std::move(first) : readKind(path, "lightmap_sh", w, h, max_texels);
    if (!img) return img.status();
    if (img->bands != bands || img->sh_index != i || img->direct_scale != b.direct_scale)
      return invalidInput("{}: coefficient {} of {} bands at direct scale {}, but lightmap_L00.exr says {} of {} at {}",
                          path, img->sh_index, img->bands, img->direct_scale, 0, bands, b.direct_scale);
    for (std::size_t t = 0; t < texels; ++t)
      for (int ch = 0; ch < 3; ++ch) b.lightmap_sh[t * 3 * nc + std::size_t(ch * nc + i)] = img->values[3 * t + ch];
  }
  auto valid = readKind((d / "valid.exr").string(), "valid", w, h, max_texels);
  if (!valid) return valid.status();
  b.valid.resize(texels);
  for (std::size_t t = 0; t < texels; ++t) b.valid[t] = valid->values[t] > 0.5f ? 1.0f : 0.0f;
  const int dw = w * b.direct_scale, dh = h * b.direct_scale;
  auto direct = readKind((d / "direct.exr").string(), "direct", dw, dh, max_texels);
  if (!direct) return direct.status();
  b.direct = toVec3(direct->values);
  b.direct_width = dw;
  b.direct_height = dh;
  b.direct_valid.clear();
  if (b.direct_scale > 1) {  // the direct layer is finer: its own validity
    auto dvalid = readKind((d / "direct_valid.exr").string(), "direct_valid", dw, dh, max_texels);
    if (!dvalid) return dvalid.status();
    b.direct_valid.resize(dvalid->values.size());
    for (std::size_t t = 0; t < b.direct_valid.size(); ++t) b.direct_valid[t] = dvalid->values[t] > 0.5f ? 1.0f : 0.0f;
  }
  return {};
}

Status readIrradianceExr(const std::string& path, BakedLighting& b, std::uint64_t max_texels) {
  auto img = readKind(path, "irradiance", 0, 0, max_texels);
  if (!img) return img.status();
  b.bands = 0;
  b.width = img->width;
  b.height = img->height;
  b.direct_scale = 1;
  b.lightmap_sh.clear();
  b.irradiance = toVec3(img->values);
  b.valid.assign(b.irradiance.size(), 1.0f);
  b.direct.clear();
  b.direct_valid.clear();
  b.direct_width = b.direct_height = 0;
  return {};
}

Status readGridRaw(const std::string& path, BakedLighting& b) {
  constexpr std::uint64_t kHeaderBytes = 48;
  auto file_bytes = regularFileSize(path);
  if (!file_bytes) return file_bytes.status();
  std::ifstream in(path, std::ios::binary);
  if (!in) return ioError("cannot open {}", path);
  char magic[8];
  std::uint64_t version = 0;
  std::uint32_t bands = 0, dims[3] = {};
  float origin[3] = {}, spacing = 0.0f;
  if (*file_bytes < kHeaderBytes)
    return invalidInput("{}: {} bytes, shorter than the 48-byte header", path, *file_bytes);
  if (!readExactly(in, magic, 8) || !readExactly(in, &version, 8) || !readExactly(in, &bands, 4) ||
      !readExactly(in, dims, 12) || !readExactly(in, origin, 12) || !readExactly(in, &spacing, 4))
    return ioError("{}: cannot read the header", path);
  if (std::memcmp(magic, "LLGRID01", 8) != 0) return invalidInput("{} is not a lightlink grid (bad magic)", path);
  if (bands < 1 || bands > 4) return invalidInput("{}: field 'bands' is {} (must be 1..4)", path, bands);
  // Each dim is bounded first, so the product cannot overflow (2^24 * 2^24 < 2^64).
  std::uint64_t points = 1;
  for (int a = 0; a < 3; ++a) {
    if (dims[a] < 1 || dims[a] > kMaxGridPoints || points * dims[a] > kMaxGridPoints)
      return invalidInput("{}: field 'dims' ({} x {} x {}) is out of range (each at least 1, at most {} points)",
                          path, dims[0], dims[1], dims[2], kMaxGridPoints);
    points *= dims[a];
  }
  if (!finite3(origin))
    return invalidInput("{}: field 'origin' ({}, {}, {}) is not finite", path, origin[0], origin[1], origin[2]);
  if (!std::isfinite(spacing) || spacing <= 0.0f)
    return invalidInput("{}: field 'spacing' ({}) must be a finite positive number", path, spacing);
  for (int a = 0; a < 3; ++a)
    if (!std::isfinite(origin[a] + spacing * float(dims[a])))
      return invalidInput("{}: fields 'origin' and 'spacing' put the grid's far corner beyond float range", path);
  const std::uint64_t per_point = 3ull * bands * bands * sizeof(float) + 1;
  const std::uint64_t expected = kHeaderBytes + points * per_point;
  if (*file_bytes != expected)
    return invalidInput("{}: {} bytes, but bands {} and dims {} x {} x {} need {} (48-byte header + {} points x {} bytes)",
                        path, *file_bytes, bands, dims[0], dims[1], dims[2], expected, points, per_point);
  const std::size_t n = std::size_t(points), per = 3 * std::size_t(bands) * bands;
  std::vector<float> sh(n * per);
  std::vector<std::uint8_t> valid(n);
  if (!readExactly(in, sh.data(), sh.size() * sizeof(float)) || !readExactly(in, valid.data(), n))
    return ioError("{}: cannot read the grid values", path);
  for (std::size_t i = 0; i < sh.size(); ++i)
    if (!std::isfinite(sh[i])) return invalidInput("{}: SH value {} of grid point {} is not finite", path, i % per, i / per);
  for (std::size_t i = 0; i < n; ++i)
    if (valid[i] > 1) return invalidInput("{}: validity of grid point {} is {} (must be 0 or 1)", path, i, valid[i]);
  b.dims = glm::ivec3(int(dims[0]), int(dims[1]), int(dims[2]));
  b.origin = glm::vec3(origin[0], origin[1], origin[2]);
  b.spacing_m = spacing;
  b.grid_sh = std::move(sh);
  b.grid_valid.assign(valid.begin(), valid.end());
  b.has_grid = true;
  b.grid_bands = int(bands);
  (void)version;
  return {};
}

namespace {

// The four bilinear taps of a w x h texel image at UV uv, each weighted by its validity;
// calls tap(texel, weight) for every tap of positive weight.
template <typename Tap>
void bilinearTaps(glm::vec2 uv, int w, int h, const std::vector<float>& valid, Tap&& tap) {
  // Clamped before the int conversion (a huge UV would overflow it); the lookup clamps to the
  // edge texels anyway.
  const float fx = std::clamp(uv.x * float(w) - 0.5f, -1.0f, float(w)),
              fy = std::clamp(uv.y * float(h) - 0.5f, -1.0f, float(h));
  const int x0 = static_cast<int>(std::floor(fx)), y0 = static_cast<int>(std::floor(fy));
  const float ax = fx - float(x0), ay = fy - float(y0);
  for (int dy = 0; dy < 2; ++dy)
    for (int dx = 0; dx < 2; ++dx) {
      const int x = std::clamp(x0 + dx, 0, w - 1), y = std::clamp(y0 + dy, 0, h - 1);
      const std::size_t t = std::size_t(y) * w + x;
      const float wt = (dx ? ax : 1 - ax) * (dy ? ay : 1 - ay) * valid[t];
      if (wt > 0.0f) tap(t, wt);
    }
}

}  // namespace

bool BakedLighting::sampleLightmap(glm::vec2 uv, const glm::vec3& normal, glm::vec3& irradiance) const {
  if (width < 1 || height < 1 || !std::isfinite(uv.x) || !std::isfinite(uv.y)) return false;
  if (bands == 0) {  // L0: the irradiance map, baked for the surface's normal
    glm::vec3 e(0.0f);
    float wsum = 0.0f;
    bilinearTaps(uv, width, height, valid, [&](std::size_t t, float w) {
      e += w * this->irradiance[t];
      wsum += w;
    });
    if (wsum <= 0.0f) return false;
    irradiance = e / wsum;
    return true;
  }
  const int nc = bands * bands;
  float sh[3 * 16] = {};
  glm::vec3 dir(0.0f);
  float wsum = 0.0f;
  bilinearTaps(uv, width, height, valid, [&](std::size_t t, float w) {
    for (int k = 0; k < 3 * nc; ++k) sh[k] += w * lightmap_sh[t * 3 * nc + k];
    if (direct_scale == 1) dir += w * direct[t];
    wsum += w;
  });
  if (wsum <= 0.0f) return false;
  // SH interpolates linearly, so evaluating the weighted sum equals the weighted evaluations.
  for (int k = 0; k < 3 * nc; ++k) sh[k] /= wsum;
  if (direct_scale == 1) {
    dir /= wsum;
  } else {  // the finer direct layer: its own bilinear lookup over its valid texels
    float dsum = 0.0f;
    bilinearTaps(uv, direct_width, direct_height, direct_valid, [&](std::size_t t, float w) {
      dir += w * direct[t];
      dsum += w;
    });
    if (dsum > 0.0f) dir /= dsum;
  }
  irradiance = shIrradiance(sh, bands, normal) + dir;
  return true;
}

bool BakedLighting::sampleGrid(const glm::vec3& p, const glm::vec3& normal, glm::vec3& irradiance) const {
  if (!has_grid || spacing_m <= 0.0f) return false;
  glm::vec3 g = (p - origin) / spacing_m;
  if (!std::isfinite(g.x) || !std::isfinite(g.y) || !std::isfinite(g.z)) return false;
  // Clamped to the grid before the int conversion (far points would overflow it); the
  // result is the same: outside points take the nearest edge's values.
  g = glm::clamp(g, glm::vec3(0.0f), glm::vec3(dims - 1));
  const glm::ivec3 i0 = glm::clamp(glm::ivec3(glm::floor(g)), glm::ivec3(0), dims - 1);
  const glm::vec3 a = glm::clamp(g - glm::vec3(i0), 0.0f, 1.0f);
  const int nc = grid_bands * grid_bands;
  float sh[3 * 16] = {};
  float wsum = 0.0f;
  for (int corner = 0; corner < 8; ++corner) {
    const glm::ivec3 o((corner & 1), (corner >> 1) & 1, (corner >> 2) & 1);
    const glm::ivec3 i = glm::min(i0 + o, dims - 1);
    const std::size_t idx = (std::size_t(i.z) * dims.y + i.y) * dims.x + i.x;
    const float w = (o.x ? a.x : 1 - a.x) * (o.y ? a.y : 1 - a.y) * (o.z ? a.z : 1 - a.z) * grid_valid[idx];
    if (w <= 0.0f) continue;
    for (int k = 0; k < 3 * nc; ++k) sh[k] += w * grid_sh[idx * 3 * nc + k];
    wsum += w;
  }
  if (wsum <= 0.0f) return false;
  for (int k = 0; k < 3 * nc; ++k) sh[k] /= wsum;
  irradiance = shIrradiance(sh, grid_bands, normal);
  return true;
}

Expected<BakedLighting> loadBakedLighting(const std::string& dir) {
  BakedLighting b;
  const std::filesystem::path d(dir);
  std::error_code ec;
  const auto exists = [&](const char* name) { return std::filesystem::exists(d / name, ec); };
  if (exists("lightmap_L00.exr")) {  // an L1 or L2 bake: the SH set
    if (Status s = readLightmapExrs(dir, b); !s) return s;
  } else if (exists("irradiance.exr")) {  // an L0 bake
    if (Status s = readIrradianceExr((d / "irradiance.exr").string(), b); !s) return s;
  } else if (exists("lightmap.exr")) {
    return invalidInput("{} holds a lightmap.exr of EXR layout 1, which this lightlink no longer reads: bake again "
                        "to write layout {} (lightmap_<c>.exr, irradiance.exr; docs/outputs.md)",
                        dir, output::kExrLayout);
  } else {
    return ioError("{} holds no lightmap: neither lightmap_L00.exr (an L1/L2 bake) nor irradiance.exr (L0)", dir);
  }
  const std::string grid = (d / "grid.raw").string();
  if (std::filesystem::exists(grid, ec)) {
    if (Status s = readGridRaw(grid, b); !s) return s;
    const int expected = b.bands == 0 ? 1 : b.bands;  // an L0 bake keeps the grid's L00
    if (b.grid_bands != expected)
      return invalidInput("{}: field 'bands' is {}, but the lightmap's encoding keeps {}", grid, b.grid_bands,
                          expected);
  }
  return b;
}

}  // namespace lightlink::viewer
