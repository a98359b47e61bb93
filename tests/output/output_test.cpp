#include "core/output/output.h"

#include <cstring>
#include <filesystem>
#include <fstream>

#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfInputFile.h>
#include <OpenEXR/ImfIntAttribute.h>
#include <OpenEXR/ImfStringAttribute.h>
#include <gtest/gtest.h>
#include <png.h>

#include "core/common/half.h"
#include "tests/common/testing.h"
#include "tests/relight/relight_fixture.h"

namespace lightlink::output {
namespace {

using namespace lightlink::relight::testing;

struct Lit {
  std::unique_ptr<Baked> baked;
  relight::RelightResult result;
  Lit() {
    scene::Scene s;
    const int m = addMaterial(s, glm::vec3(0.6f, 0.4f, 0.3f));
    const int e = addMaterial(s, glm::vec3(0.5f), glm::vec3(3.0f, 2.0f, 1.0f));
    addBox(s, {0, 0, 0}, {2, 2, 2}, /*inward=*/true, m);
    addQuad(s, {0.8f, 1.99f, 0.8f}, {1.2f, 1.99f, 0.8f}, {1.2f, 1.99f, 1.2f}, {0.8f, 1.99f, 1.2f}, e);
    auto o = smallOptions();
    o.grid = precompute::GridMode::kOn;
    o.grid_resolution = 4;
    baked = Baked::make(std::move(s), o);
    if (!baked) return;
    relight::Relighter r = baked->relighter();
    relight::LightSet set;
    relight::LightEntry lamp;
    lamp.id = "lamp";
    lamp.light.position = {1.0f, 1.5f, 1.0f};
    lamp.light.intensity = 100000.0f;  // strong enough that some direct texels exceed the half range
    EXPECT_TRUE(set.add(lamp));
    auto res = r.relight(set, {.max_bounces = 2});
    EXPECT_TRUE(res);
    if (res) result = std::move(res).value();
  }
};

const Lit& lit() {
  static Lit l;
  return l;
}

// Reads every channel of an EXR as float planes (OpenEXR converts half to float exactly).
struct ExrImage {
  int width = 0, height = 0;
  std::vector<std::string> names;
  std::vector<Imf::PixelType> types;
  std::vector<std::vector<float>> planes;
  Imf::Header header;
};

ExrImage readExr(const std::string& path) {
  ExrImage img;
  Imf::InputFile file(path.c_str());
  img.header = file.header();
  const auto dw = file.header().dataWindow();
  img.width = dw.max.x - dw.min.x + 1;
  img.height = dw.max.y - dw.min.y + 1;
  Imf::FrameBuffer fb;
  for (auto it = file.header().channels().begin(); it != file.header().channels().end(); ++it) {
    img.names.push_back(it.name());
    img.types.push_back(it.channel().type);
  }
  img.planes.resize(img.names.size());
  for (std::size_t c = 0; c < img.names.size(); ++c) {
    img.planes[c].assign(std::size_t(img.width) * img.height, -1.0f);
    fb.insert(img.names[c], Imf::Slice(Imf::FLOAT, reinterpret_cast<char*>(img.planes[c].data()), sizeof(float),
                                       sizeof(float) * img.width));
  }
  file.setFrameBuffer(fb);
  file.readPixels(dw.min.y, dw.max.y);
  return img;
}

const std::vector<float>& plane(const ExrImage& img, const std::string& name) {
  for (std::size_t c = 0; c < img.names.size(); ++c)
    if (img.names[c] == name) return img.planes[c];
  ADD_FAILURE() << "no channel " << name;
  static const std::vector<float> empty;
  return empty;
}

TEST(Output, LayerNames) {
  const std::vector<std::string> expected = {"L00",  "L1m1", "L10", "L11",  "L2m2", "L2m1", "L20", "L21",
                                             "L22",  "L3m3", "L3m2", "L3m1", "L30",  "L31",  "L32", "L33"};
  for (int i = 0; i < 16; ++i) EXPECT_EQ(shLayerName(i), expected[i]);
}

TEST(Output, LightmapExrRoundTripsFloatBitExactlyAndHalfWithinRounding) {
  const auto& l = lit();
  ASSERT_TRUE(l.baked);
  const auto& r = l.result;
  const int nc = r.coeffCount();
  ASSERT_EQ(nc, 9);
  testing::TempDir dir;
  for (bool half : {false, true}) {
    const std::string path = (dir / (half ? "lm_half.exr" : "lm_float.exr")).string();
    auto stats = writeLightmapExr(r, path, {.half = half, .scene_hash = "abc123"});
    ASSERT_TRUE(stats) << stats.status().toString();
    const ExrImage img = readExr(path);
    ASSERT_EQ(img.width, r.width);
    ASSERT_EQ(img.height, r.height);
    ASSERT_EQ(img.names.size(), std::size_t(3 * nc + 3 + 1));
    for (auto t : img.types) EXPECT_EQ(t, half ? Imf::HALF : Imf::FLOAT);
    const char* ch[3] = {"R", "G", "B"};
    bool clamped_unused = false;
    for (int i = 0; i < nc; ++i)
      for (int c = 0; c < 3; ++c) {
        const auto& p = plane(img, shLayerName(i) + "." + ch[c]);
        for (std::size_t t = 0; t < p.size(); ++t) {
          const float v = r.lightmap_sh[t * 3 * nc + c * nc + i];
          if (half) {
            const float expected = fromHalf(toHalfSaturating(v, clamped_unused));
            ASSERT_EQ(p[t], expected) << shLayerName(i) << " texel " << t;
            ASSERT_LE(std::abs(p[t] - v), std::abs(v) * 1e-3f + 1e-7f);
          } else {
            ASSERT_EQ(std::memcmp(&p[t], &v, sizeof(float)), 0) << shLayerName(i) << " texel " << t;
          }
        }
      }
    const auto& dr = plane(img, "direct.R");
    std::size_t over = 0;
    for (std::size_t t = 0; t < dr.size(); ++t) {
      if (half) {
        over += r.direct[t].x > kHalfMax;
        ASSERT_EQ(dr[t], fromHalf(toHalfSaturating(r.direct[t].x, clamped_unused)));
      } else {
        ASSERT_EQ(dr[t], r.direct[t].x);
      }
    }
    if (half) {
      EXPECT_GT(over, 0u) << "the fixture should exceed the half range somewhere";
      EXPECT_GE(stats->clamped, over);
    } else {
      EXPECT_EQ(stats->clamped, 0u);
    }
    const auto& valid = plane(img, "valid.Y");
    for (std::size_t t = 0; t < valid.size(); ++t) ASSERT_EQ(valid[t], r.texel_valid[t] ? 1.0f : 0.0f);
    const auto* bands = img.header.findTypedAttribute<Imf::IntAttribute>("lightlink.bands");
    ASSERT_NE(bands, nullptr);
    EXPECT_EQ(bands->value(), 3);
    const auto* hash = img.header.findTypedAttribute<Imf::StringAttribute>("lightlink.scene_hash");
    ASSERT_NE(hash, nullptr);
    EXPECT_EQ(hash->value(), "abc123");
    const auto* conv = img.header.findTypedAttribute<Imf::StringAttribute>("lightlink.sh_convention");
    ASSERT_NE(conv, nullptr);
    EXPECT_NE(conv->value().find("l*l+l+m"), std::string::npos);
    EXPECT_NE(img.header.findTypedAttribute<Imf::StringAttribute>("lightlink.version"), nullptr);
    EXPECT_NE(img.header.findTypedAttribute<Imf::StringAttribute>("lightlink.units"), nullptr);
  }
}

TEST(Output, GridExrJsonAndRawAgree) {
  const auto& l = lit();
  ASSERT_TRUE(l.baked);
  const auto& r = l.result;
  const auto& grid = l.baked->p.grid;
  ASSERT_GT(grid.size(), 0u);
  testing::TempDir dir;
  const std::string exr = (dir / "grid.exr").string(), json = (dir / "grid.json").string(),
                    raw = (dir / "grid.raw").string();
  ASSERT_TRUE(writeGridExr(r, grid, exr, {.half = false}));
  ASSERT_TRUE(writeGridJson(r, grid, json));
  ASSERT_TRUE(writeGridRaw(r, grid, raw));
  const ExrImage img = readExr(exr);
  ASSERT_EQ(img.width, grid.dims.x * grid.dims.z);
  ASSERT_EQ(img.height, grid.dims.y);
  const int nc = r.coeffCount();
  const auto& l00 = plane(img, "L00.G");
  for (int z = 0; z < grid.dims.z; ++z)
    for (int y = 0; y < grid.dims.y; ++y)
      for (int x = 0; x < grid.dims.x; ++x) {
        const std::size_t e = (std::size_t(z) * grid.dims.y + y) * grid.dims.x + x;
        ASSERT_EQ(l00[std::size_t(y) * img.width + z * grid.dims.x + x], r.grid_sh[e * 3 * nc + nc]);
      }
  std::ifstream in(raw, std::ios::binary);
  char magic[8];
  in.read(magic, 8);
  EXPECT_EQ(std::string(magic, 8), "LLGRID01");
  std::uint64_t version;
  std::uint32_t bands, dims[3];
  float origin[3], spacing;
  in.read(reinterpret_cast<char*>(&version), 8);
  in.read(reinterpret_cast<char*>(&bands), 4);
  in.read(reinterpret_cast<char*>(dims), 12);
  in.read(reinterpret_cast<char*>(origin), 12);
  in.read(reinterpret_cast<char*>(&spacing), 4);
  EXPECT_EQ(version, r.version);
  EXPECT_EQ(bands, 3u);
  EXPECT_EQ(int(dims[0]), grid.dims.x);
  EXPECT_EQ(spacing, grid.spacing_m);
  std::vector<float> data(r.grid_sh.size());
  in.read(reinterpret_cast<char*>(data.data()), std::streamsize(data.size() * 4));
  std::vector<std::uint8_t> valid(grid.size());
  in.read(reinterpret_cast<char*>(valid.data()), std::streamsize(valid.size()));
  ASSERT_TRUE(in);
  EXPECT_EQ(data, r.grid_sh);
  EXPECT_EQ(valid, grid.valid);
  EXPECT_EQ(in.peek(), EOF);
  auto meta = nlohmann::json::parse(std::ifstream(json));
  EXPECT_EQ(meta["dims"][2].get<int>(), grid.dims.z);
  EXPECT_EQ(meta["sh_layers"].size(), 9u);
  EXPECT_EQ(meta["valid"].size(), grid.size());
}

TEST(Output, PreviewPngIsWrittenAndNotBlank) {
  const auto& l = lit();
  ASSERT_TRUE(l.baked);
  testing::TempDir dir;
  const std::string path = (dir / "preview.png").string();
  ASSERT_TRUE(writeIrradiancePng(l.result, l.baked->p.lightmap, path));
  ASSERT_GT(std::filesystem::file_size(path), 100u);
  png_image image{};
  image.version = PNG_IMAGE_VERSION;
  ASSERT_TRUE(png_image_begin_read_from_file(&image, path.c_str()));
  image.format = PNG_FORMAT_RGB;
  std::vector<std::uint8_t> rgb(PNG_IMAGE_SIZE(image));
  ASSERT_TRUE(png_image_finish_read(&image, nullptr, rgb.data(), 0, nullptr));
  EXPECT_EQ(int(image.width), l.result.width);
  std::size_t bright = 0;
  for (std::size_t i = 0; i < rgb.size(); i += 3) bright += rgb[i] > 64;
  EXPECT_GT(bright, rgb.size() / 3 / 10);
  ASSERT_TRUE(writeReportJson(l.result.report(), (dir / "report.json").string()));
  auto report = nlohmann::json::parse(std::ifstream((dir / "report.json").string()));
  EXPECT_EQ(report["backend"], "cpu");
  EXPECT_TRUE(report["effects_plan"]["baked_direct"].get<bool>());
}

TEST(Output, RejectsAResultWithoutGrid) {
  relight::RelightResult empty;
  caches::GridCaches grid;
  testing::TempDir dir;
  EXPECT_FALSE(writeGridExr(empty, grid, (dir / "g.exr").string()));
  EXPECT_FALSE(writeLightmapExr(empty, (dir / "l.exr").string()));
}

}  // namespace
}  // namespace lightlink::output
