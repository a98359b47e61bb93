#include "core/output/output.h"

#include <algorithm>
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
#include "core/sh/sh.h"
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

int intAttr(const ExrImage& img, const char* name) {
  const auto* a = img.header.findTypedAttribute<Imf::IntAttribute>(name);
  EXPECT_NE(a, nullptr) << name;
  return a ? a->value() : -999;
}

std::string stringAttr(const ExrImage& img, const char* name) {
  const auto* a = img.header.findTypedAttribute<Imf::StringAttribute>(name);
  EXPECT_NE(a, nullptr) << name;
  return a ? a->value() : "";
}

std::vector<std::string> filesIn(const std::filesystem::path& dir) {
  std::vector<std::string> names;
  for (const auto& e : std::filesystem::directory_iterator(dir)) names.push_back(e.path().filename().string());
  std::sort(names.begin(), names.end());
  return names;
}

TEST(Output, LightmapExrsRoundTripFloatBitExactlyAndHalfWithinRounding) {
  const auto& l = lit();
  ASSERT_TRUE(l.baked);
  const auto& r = l.result;
  const int nc = r.coeffCount();
  ASSERT_EQ(nc, 9);
  ASSERT_FALSE(r.directIsFiner()) << "this test reads direct.exr at the lightmap's size";
  testing::TempDir dir;
  for (bool half : {false, true}) {
    const std::filesystem::path sub = dir / (half ? "half" : "float");
    std::filesystem::create_directories(sub);
    auto written = writeLightmapExrs(r, l.baked->p.lightmap, sub.string(), {.half = half, .scene_hash = "abc123"});
    ASSERT_TRUE(written) << written.status().toString();
    std::vector<std::string> expected_files = {"irradiance.exr"};
    for (int i = 0; i < nc; ++i) expected_files.push_back("lightmap_" + shLayerName(i) + ".exr");
    expected_files.insert(expected_files.end(), {"direct.exr", "valid.exr"});
    EXPECT_EQ(written->files, expected_files);
    bool clamped_unused = false;
    const auto stored = [&](float v) {
      return half ? fromHalf(toHalfSaturating(v, clamped_unused)) : v;
    };
    for (int i = 0; i < nc; ++i) {
      const ExrImage img = readExr((sub / ("lightmap_" + shLayerName(i) + ".exr")).string());
      ASSERT_EQ(img.width, r.width);
      ASSERT_EQ(img.height, r.height);
      // Plain R, G, B channels: what three.js's EXRLoader and every EXR reader load.
      ASSERT_EQ(img.names, (std::vector<std::string>{"B", "G", "R"}));
      for (auto t : img.types) EXPECT_EQ(t, half ? Imf::HALF : Imf::FLOAT);
      EXPECT_EQ(intAttr(img, "lightlink.layout"), kExrLayout);
      EXPECT_EQ(intAttr(img, "lightlink.sh_index"), i);
      EXPECT_EQ(intAttr(img, "lightlink.bands"), 3);
      EXPECT_EQ(stringAttr(img, "lightlink.kind"), "lightmap_sh");
      EXPECT_EQ(stringAttr(img, "lightlink.encoding"), "l2");
      EXPECT_EQ(stringAttr(img, "lightlink.scene_hash"), "abc123");
      EXPECT_NE(stringAttr(img, "lightlink.sh_convention").find("l*l+l+m"), std::string::npos);
      const char* ch[3] = {"R", "G", "B"};
      for (int c = 0; c < 3; ++c) {
        const auto& p = plane(img, ch[c]);
        for (std::size_t t = 0; t < p.size(); ++t) {
          const float v = r.lightmap_sh[t * 3 * nc + c * nc + i];
          if (half) {
            ASSERT_EQ(p[t], stored(v)) << shLayerName(i) << " texel " << t;
            ASSERT_LE(std::abs(p[t] - v), std::abs(v) * 1e-3f + 1e-7f);
          } else {
            ASSERT_EQ(std::memcmp(&p[t], &v, sizeof(float)), 0) << shLayerName(i) << " texel " << t;
          }
        }
      }
    }
    const ExrImage direct = readExr((sub / "direct.exr").string());
    const auto& dr = plane(direct, "R");
    std::size_t over = 0;
    for (std::size_t t = 0; t < dr.size(); ++t) {
      over += half && r.direct[t].x > kHalfMax;
      ASSERT_EQ(dr[t], stored(r.direct[t].x));
    }
    if (half) {
      EXPECT_GT(over, 0u) << "the fixture should exceed the half range somewhere";
      EXPECT_GE(written->stats.clamped, over);
    } else {
      EXPECT_EQ(written->stats.clamped, 0u);
    }
    const ExrImage valid = readExr((sub / "valid.exr").string());
    ASSERT_EQ(valid.names, std::vector<std::string>{"Y"});
    const auto& vy = plane(valid, "Y");
    for (std::size_t t = 0; t < vy.size(); ++t) ASSERT_EQ(vy[t], r.texel_valid[t] ? 1.0f : 0.0f);
  }
}

// Each encoding written, read back with OpenEXR (not lightlink's reader) and evaluated as an
// engine would (docs/outputs.md), against the in-memory result: L0 is irradiance.exr, L1 the
// 4-coefficient evaluation, L2 the 9-coefficient one, at every valid texel's cache normal.
TEST(Output, EncodingsRoundTripAgainstTheInMemoryResult) {
  const auto& l = lit();
  ASSERT_TRUE(l.baked);
  const auto& r = l.result;
  const auto& caches = l.baked->p.lightmap;
  const int nc = r.coeffCount();
  testing::TempDir dir;
  double l1_vs_l2 = 0.0, l2_sum = 0.0;
  for (const Encoding e : {Encoding::kL0, Encoding::kL1, Encoding::kL2}) {
    const std::filesystem::path sub = dir / std::string(encodingName(e));
    std::filesystem::create_directories(sub);
    auto written = writeLightmapExrs(r, caches, sub.string(), {.half = false, .encoding = e});
    ASSERT_TRUE(written) << written.status().toString();
    EXPECT_EQ(filesIn(sub).size(), written->files.size());
    const int bands = lightmapBands(e, r.bands);
    EXPECT_EQ(bands, e == Encoding::kL0 ? 0 : e == Encoding::kL1 ? 2 : 3);
    EXPECT_EQ(std::filesystem::exists(sub / "lightmap_L00.exr"), bands > 0);
    EXPECT_EQ(std::filesystem::exists(sub / "lightmap_L2m2.exr"), bands > 2);
    // L0: irradiance.exr holds, per valid texel, the SH at the cache normal plus direct.
    const ExrImage irr = readExr((sub / "irradiance.exr").string());
    ASSERT_EQ(irr.names, (std::vector<std::string>{"B", "G", "R"}));
    EXPECT_EQ(stringAttr(irr, "lightlink.kind"), "irradiance");
    EXPECT_EQ(stringAttr(irr, "lightlink.encoding"), std::string(encodingName(e)));
    // The SH files as read back: per coefficient one image of R, G, B planes.
    std::vector<ExrImage> sh_files;
    for (int i = 0; i < bands * bands; ++i) {
      sh_files.push_back(readExr((sub / ("lightmap_" + shLayerName(i) + ".exr")).string()));
      EXPECT_EQ(intAttr(sh_files.back(), "lightlink.bands"), bands);
    }
    const char* kCh[3] = {"R", "G", "B"};
    std::vector<float> coeffs(static_cast<std::size_t>(nc));
    std::size_t checked = 0, dilated = 0;
    for (std::size_t t = 0; t < r.texel_valid.size(); ++t) {
      const std::int32_t c = caches.cache_of_texel[t];
      if (!r.texel_valid[t]) {
        ASSERT_EQ(plane(irr, "R")[t], 0.0f) << "texel " << t << " holds no value";
        continue;
      }
      if (c < 0) {  // a dilated texel: the mean of its evaluated neighbours, never black
        EXPECT_GT(plane(irr, "R")[t] + plane(irr, "G")[t] + plane(irr, "B")[t], 0.0f) << "dilated texel " << t;
        ++dilated;
        continue;
      }
      const glm::vec3 n = caches.normal[c];
      const float* sh = r.lightmap_sh.data() + t * 3 * nc;
      for (int ch = 0; ch < 3; ++ch) {
        const float full = sh::irradiance(r.bands, sh + ch * nc, n);
        ASSERT_EQ(plane(irr, kCh[ch])[t], full + r.direct[t][ch]) << "texel " << t;
        if (bands == 0) continue;
        // The SH files evaluated as the engine does, against the same bands of the result.
        for (int i = 0; i < bands * bands; ++i) coeffs[std::size_t(i)] = plane(sh_files[std::size_t(i)], kCh[ch])[t];
        const float got = sh::irradiance(bands, coeffs.data(), n);
        ASSERT_EQ(got, sh::irradiance(bands, sh + ch * nc, n)) << encodingName(e) << " texel " << t;
        if (e == Encoding::kL1) {
          l1_vs_l2 += std::abs(got - full);
          l2_sum += full;
        }
      }
      ++checked;
    }
    EXPECT_GT(checked, 100u);
    EXPECT_GT(dilated, 0u) << "the fixture's lightmap has dilated gutter texels";
  }
  // L1 drops band 2: close to, but not the same as, L2 in this lit box.
  EXPECT_GT(l1_vs_l2, 0.0);
  EXPECT_LT(l1_vs_l2 / l2_sum, 0.2) << "mean |L1 - L2| / mean L2";
}

TEST(Output, GridExrsJsonAndRawAgreeForEachEncoding) {
  const auto& l = lit();
  ASSERT_TRUE(l.baked);
  const auto& r = l.result;
  const auto& grid = l.baked->p.grid;
  ASSERT_GT(grid.size(), 0u);
  const int nc = r.coeffCount();
  for (const Encoding e : {Encoding::kL0, Encoding::kL1, Encoding::kL2}) {
    testing::TempDir dir;
    const std::string json = (dir / "grid.json").string(), raw = (dir / "grid.raw").string();
    auto written = writeGridExrs(r, grid, dir.path().string(), {.half = false, .encoding = e});
    ASSERT_TRUE(written) << written.status().toString();
    ASSERT_TRUE(writeGridJson(r, grid, json, e));
    ASSERT_TRUE(writeGridRaw(r, grid, raw, e));
    const int bands = gridBands(e, r.bands);
    EXPECT_EQ(bands, e == Encoding::kL0 ? 1 : e == Encoding::kL1 ? 2 : 3);
    EXPECT_EQ(written->files.size(), std::size_t(bands * bands + 1));
    const int gnc = bands * bands;
    for (int i = 0; i < gnc; ++i) {
      const ExrImage img = readExr((dir / ("grid_" + shLayerName(i) + ".exr")).string());
      ASSERT_EQ(img.width, grid.dims.x * grid.dims.z);
      ASSERT_EQ(img.height, grid.dims.y);
      EXPECT_EQ(stringAttr(img, "lightlink.kind"), "grid_sh");
      const auto& g = plane(img, "G");
      for (int z = 0; z < grid.dims.z; ++z)
        for (int y = 0; y < grid.dims.y; ++y)
          for (int x = 0; x < grid.dims.x; ++x) {
            const std::size_t c = (std::size_t(z) * grid.dims.y + y) * grid.dims.x + x;
            ASSERT_EQ(g[std::size_t(y) * img.width + z * grid.dims.x + x], r.grid_sh[c * 3 * nc + nc + i]);
          }
    }
    EXPECT_FALSE(std::filesystem::exists(dir / ("grid_" + shLayerName(gnc) + ".exr")));
    const ExrImage valid = readExr((dir / "grid_valid.exr").string());
    ASSERT_EQ(valid.names, std::vector<std::string>{"Y"});
    std::ifstream in(raw, std::ios::binary);
    char magic[8];
    in.read(magic, 8);
    EXPECT_EQ(std::string(magic, 8), "LLGRID01");
    std::uint64_t version;
    std::uint32_t raw_bands, dims[3];
    float origin[3], spacing;
    in.read(reinterpret_cast<char*>(&version), 8);
    in.read(reinterpret_cast<char*>(&raw_bands), 4);
    in.read(reinterpret_cast<char*>(dims), 12);
    in.read(reinterpret_cast<char*>(origin), 12);
    in.read(reinterpret_cast<char*>(&spacing), 4);
    EXPECT_EQ(version, r.version);
    EXPECT_EQ(raw_bands, std::uint32_t(bands));
    EXPECT_EQ(int(dims[0]), grid.dims.x);
    EXPECT_EQ(spacing, grid.spacing_m);
    std::vector<float> data(grid.size() * 3 * std::size_t(gnc));
    in.read(reinterpret_cast<char*>(data.data()), std::streamsize(data.size() * 4));
    std::vector<std::uint8_t> valid_raw(grid.size());
    in.read(reinterpret_cast<char*>(valid_raw.data()), std::streamsize(valid_raw.size()));
    ASSERT_TRUE(in);
    EXPECT_EQ(data, truncateSh(r.grid_sh, r.bands, bands));
    EXPECT_EQ(valid_raw, grid.valid);
    EXPECT_EQ(in.peek(), EOF);
    auto meta = nlohmann::json::parse(std::ifstream(json));
    EXPECT_EQ(meta["dims"][2].get<int>(), grid.dims.z);
    EXPECT_EQ(meta["bands"].get<int>(), bands);
    EXPECT_EQ(meta["sh_files"].size(), std::size_t(gnc));
    EXPECT_EQ(meta["valid"].size(), grid.size());
  }
}

TEST(Output, ParsesEncodingsAndRejectsOthersNamingTheChoices) {
  EXPECT_EQ(*parseEncoding("l0"), Encoding::kL0);
  EXPECT_EQ(*parseEncoding("l1"), Encoding::kL1);
  EXPECT_EQ(*parseEncoding("l2"), Encoding::kL2);
  const auto bad = parseEncoding("L2");
  ASSERT_FALSE(bad);
  EXPECT_NE(bad.status().message().find("l0"), std::string::npos) << bad.status().message();
  // Truncation keeps each channel's first coefficients.
  const std::vector<float> two_texels_l2 = [] {
    std::vector<float> v(2 * 27);
    for (std::size_t i = 0; i < v.size(); ++i) v[i] = float(i);
    return v;
  }();
  const std::vector<float> l1 = truncateSh(two_texels_l2, 3, 2);
  ASSERT_EQ(l1.size(), 2u * 12u);
  EXPECT_EQ(l1[4], 9.0f);    // texel 0, G, L00
  EXPECT_EQ(l1[12], 27.0f);  // texel 1, R, L00
  EXPECT_EQ(l1[23], 48.0f);  // texel 1, B, L11
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
  EXPECT_FALSE(writeGridExrs(empty, grid, dir.path().string()));
  EXPECT_FALSE(writeLightmapExrs(empty, caches::LightmapCaches{}, dir.path().string()));
}

}  // namespace
}  // namespace lightlink::output
