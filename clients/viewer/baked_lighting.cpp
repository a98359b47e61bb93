#include "clients/viewer/baked_lighting.h"

#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>

#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfInputFile.h>
#include <OpenEXR/ImfIntAttribute.h>

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

Status readLightmap(const std::string& path, BakedLighting& b) {
  try {
    Imf::InputFile file(path.c_str());
    const Imf::Header& h = file.header();
    const auto* bands = h.findTypedAttribute<Imf::IntAttribute>("lightlink.bands");
    if (bands == nullptr || bands->value() < 1 || bands->value() > 4)
      return invalidInput("{} is not a lightlink lightmap (no valid lightlink.bands attribute)", path);
    b.bands = bands->value();
    const Imath::Box2i dw = h.dataWindow();
    b.width = dw.max.x - dw.min.x + 1;
    b.height = dw.max.y - dw.min.y + 1;
    const std::size_t texels = std::size_t(b.width) * b.height, nc = std::size_t(b.bands) * b.bands;
    // Read channel by channel into planar float buffers, then interleave per texel.
    std::vector<std::vector<float>> planes(3 * nc + 4, std::vector<float>(texels, 0.0f));
    Imf::FrameBuffer fb;
    auto slice = [&](const std::string& name, std::vector<float>& plane) {
      if (h.channels().findChannel(name.c_str()) == nullptr) return false;
      char* base = reinterpret_cast<char*>(plane.data()) -
                   (std::ptrdiff_t(dw.min.x) + std::ptrdiff_t(dw.min.y) * b.width) * std::ptrdiff_t(sizeof(float));
      fb.insert(name.c_str(), Imf::Slice(Imf::FLOAT, base, sizeof(float), sizeof(float) * b.width));
      return true;
    };
    const char* rgb[3] = {".R", ".G", ".B"};
    for (std::size_t i = 0; i < nc; ++i)
      for (int ch = 0; ch < 3; ++ch)
        if (!slice(output::shLayerName(static_cast<int>(i)) + rgb[ch], planes[ch * nc + i]))
          return invalidInput("{}: channel {}{} is missing", path, output::shLayerName(static_cast<int>(i)), rgb[ch]);
    for (int ch = 0; ch < 3; ++ch) slice(std::string("direct") + rgb[ch], planes[3 * nc + ch]);
    if (!slice("valid.Y", planes[3 * nc + 3])) return invalidInput("{}: channel valid.Y is missing", path);
    file.setFrameBuffer(fb);
    file.readPixels(dw.min.y, dw.max.y);
    b.lightmap_sh.resize(texels * 3 * nc);
    b.direct.resize(texels);
    b.valid.resize(texels);
    for (std::size_t t = 0; t < texels; ++t) {
      for (std::size_t k = 0; k < 3 * nc; ++k) b.lightmap_sh[t * 3 * nc + k] = planes[k][t];
      b.direct[t] = {planes[3 * nc][t], planes[3 * nc + 1][t], planes[3 * nc + 2][t]};
      b.valid[t] = planes[3 * nc + 3][t] > 0.5f ? 1.0f : 0.0f;
    }
  } catch (const std::exception& e) {
    return invalidInput("cannot read lightmap {}: {}", path, e.what());
  }
  return {};
}

Status readGridRaw(const std::string& path, BakedLighting& b) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return ioError("cannot open {}", path);
  char magic[8];
  std::uint64_t version = 0;
  std::uint32_t bands = 0, dims[3] = {};
  float origin[3] = {}, spacing = 0.0f;
  in.read(magic, 8);
  in.read(reinterpret_cast<char*>(&version), 8);
  in.read(reinterpret_cast<char*>(&bands), 4);
  in.read(reinterpret_cast<char*>(dims), 12);
  in.read(reinterpret_cast<char*>(origin), 12);
  in.read(reinterpret_cast<char*>(&spacing), 4);
  if (!in || std::memcmp(magic, "LLGRID01", 8) != 0) return invalidInput("{} is not a lightlink grid (bad magic)", path);
  if (static_cast<int>(bands) != b.bands) return invalidInput("{}: {} bands, the lightmap has {}", path, bands, b.bands);
  const std::size_t n = std::size_t(dims[0]) * dims[1] * dims[2];
  if (n == 0 || n > (std::size_t(1) << 24)) return invalidInput("{}: grid of {} points is out of range", path, n);
  b.dims = glm::ivec3(dims[0], dims[1], dims[2]);
  b.origin = glm::vec3(origin[0], origin[1], origin[2]);
  b.spacing_m = spacing;
  const std::size_t per = 3 * std::size_t(bands) * bands;
  b.grid_sh.resize(n * per);
  in.read(reinterpret_cast<char*>(b.grid_sh.data()), static_cast<std::streamsize>(b.grid_sh.size() * sizeof(float)));
  std::vector<std::uint8_t> valid(n);
  in.read(reinterpret_cast<char*>(valid.data()), static_cast<std::streamsize>(n));
  if (!in) return invalidInput("{} is truncated", path);
  b.grid_valid.assign(valid.begin(), valid.end());
  b.has_grid = true;
  return {};
}

}  // namespace

bool BakedLighting::sampleLightmap(glm::vec2 uv, const glm::vec3& normal, glm::vec3& irradiance) const {
  const float fx = uv.x * float(width) - 0.5f, fy = uv.y * float(height) - 0.5f;
  const int x0 = static_cast<int>(std::floor(fx)), y0 = static_cast<int>(std::floor(fy));
  const float ax = fx - float(x0), ay = fy - float(y0);
  const int nc = bands * bands;
  float sh[3 * 16] = {};
  glm::vec3 dir(0.0f);
  float wsum = 0.0f;
  for (int dy = 0; dy < 2; ++dy)
    for (int dx = 0; dx < 2; ++dx) {
      const int x = std::clamp(x0 + dx, 0, width - 1), y = std::clamp(y0 + dy, 0, height - 1);
      const std::size_t t = std::size_t(y) * width + x;
      const float w = (dx ? ax : 1 - ax) * (dy ? ay : 1 - ay) * valid[t];
      if (w <= 0.0f) continue;
      for (int k = 0; k < 3 * nc; ++k) sh[k] += w * lightmap_sh[t * 3 * nc + k];
      dir += w * direct[t];
      wsum += w;
    }
  if (wsum <= 0.0f) return false;
  // SH interpolates linearly, so evaluating the weighted sum equals the weighted evaluations.
  for (int k = 0; k < 3 * nc; ++k) sh[k] /= wsum;
  irradiance = shIrradiance(sh, bands, normal) + dir / wsum;
  return true;
}

bool BakedLighting::sampleGrid(const glm::vec3& p, const glm::vec3& normal, glm::vec3& irradiance) const {
  if (!has_grid || spacing_m <= 0.0f) return false;
  const glm::vec3 g = (p - origin) / spacing_m;
  const glm::ivec3 i0 = glm::clamp(glm::ivec3(glm::floor(g)), glm::ivec3(0), dims - 1);
  const glm::vec3 a = glm::clamp(g - glm::vec3(i0), 0.0f, 1.0f);
  const int nc = bands * bands;
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
  irradiance = shIrradiance(sh, bands, normal);
  return true;
}

Expected<BakedLighting> loadBakedLighting(const std::string& dir) {
  BakedLighting b;
  const std::filesystem::path d(dir);
  if (Status s = readLightmap((d / "lightmap.exr").string(), b); !s) return s;
  if (std::filesystem::exists(d / "grid.raw"))
    if (Status s = readGridRaw((d / "grid.raw").string(), b); !s) return s;
  return b;
}

}  // namespace lightlink::viewer
