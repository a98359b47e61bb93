#include "clients/viewer/baked_lighting.h"

#include <array>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <limits>
#include <numbers>
#include <string>

#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfIntAttribute.h>
#include <OpenEXR/ImfOutputFile.h>
#include <gtest/gtest.h>

#include "core/output/output.h"
#include "core/relight/relight.h"
#include "core/sh/sh.h"
#include "tests/common/testing.h"

namespace lightlink::viewer {
namespace {

constexpr float kPi = std::numbers::pi_v<float>;

// A 2x2 lightmap, 1 band: texel t holds a constant radiance L_t (L00 = L sqrt(4 pi)), so
// its irradiance is pi * L_t for any normal.
BakedLighting twoByTwo(std::array<float, 4> radiance, std::array<float, 4> valid) {
  BakedLighting b;
  b.bands = 1;
  b.width = b.height = 2;
  for (int t = 0; t < 4; ++t) {
    const float c = radiance[t] * std::sqrt(4.0f * kPi);
    b.lightmap_sh.insert(b.lightmap_sh.end(), {c, c, c});
    b.direct.push_back(glm::vec3(0.0f));
    b.valid.push_back(valid[t]);
  }
  return b;
}

TEST(BakedLighting, BilinearBetweenTexelCentres) {
  const BakedLighting b = twoByTwo({1, 2, 3, 4}, {1, 1, 1, 1});
  glm::vec3 e;
  ASSERT_TRUE(b.sampleLightmap({0.5f, 0.5f}, {0, 0, 1}, e));  // the middle: mean of all four
  EXPECT_NEAR(e.x, kPi * 2.5f, 1e-4f);
  ASSERT_TRUE(b.sampleLightmap({0.25f, 0.25f}, {0, 0, 1}, e));  // texel 0's centre
  EXPECT_NEAR(e.y, kPi * 1.0f, 1e-4f);
}

TEST(BakedLighting, InvalidTexelsCarryNoWeight) {
  // Texel 3 is invalid and black: the middle must average only the three valid ones.
  const BakedLighting b = twoByTwo({1, 2, 3, 0}, {1, 1, 1, 0});
  glm::vec3 e;
  ASSERT_TRUE(b.sampleLightmap({0.5f, 0.5f}, {0, 1, 0}, e));
  EXPECT_NEAR(e.z, kPi * 2.0f, 1e-4f);
  const BakedLighting none = twoByTwo({1, 2, 3, 4}, {0, 0, 0, 0});
  EXPECT_FALSE(none.sampleLightmap({0.5f, 0.5f}, {0, 1, 0}, e));
}

TEST(BakedLighting, GridTrilinearSkipsInvalidPoints) {
  BakedLighting b;
  b.bands = 1;
  b.grid_bands = 1;
  b.has_grid = true;
  b.dims = {2, 2, 2};
  b.origin = glm::vec3(0.0f);
  b.spacing_m = 1.0f;
  for (int i = 0; i < 8; ++i) {
    const float c = float(i) * std::sqrt(4.0f * kPi);
    b.grid_sh.insert(b.grid_sh.end(), {c, c, c});
    b.grid_valid.push_back(i == 7 ? 0.0f : 1.0f);
  }
  glm::vec3 e;
  ASSERT_TRUE(b.sampleGrid({0.0f, 0.0f, 0.0f}, {1, 0, 0}, e));
  EXPECT_NEAR(e.x, 0.0f, 1e-4f);
  ASSERT_TRUE(b.sampleGrid({1.0f, 0.0f, 0.0f}, {1, 0, 0}, e));  // point 1
  EXPECT_NEAR(e.x, kPi * 1.0f, 1e-4f);
  ASSERT_TRUE(b.sampleGrid({0.5f, 0.5f, 0.5f}, {1, 0, 0}, e));  // mean of points 0..6
  EXPECT_NEAR(e.x, kPi * 3.0f, 1e-3f);
}

TEST(BakedLighting, MissingBakeIsAnErrorNamingTheFile) {
  auto b = loadBakedLighting("/no/such/bake");
  ASSERT_FALSE(b);
  EXPECT_NE(b.status().message().find("lightmap_L00.exr"), std::string::npos) << b.status().message();
  EXPECT_NE(b.status().message().find("irradiance.exr"), std::string::npos) << b.status().message();
}

// Lightmap caches for a w x h result with one cache per texel, all facing +y: what
// writeLightmapExrs needs to evaluate irradiance.exr.
caches::LightmapCaches flatCaches(int w, int h) {
  caches::LightmapCaches c;
  c.width = w;
  c.height = h;
  for (int t = 0; t < w * h; ++t) {
    c.cache_of_texel.push_back(t);
    c.normal.push_back({0.0f, 1.0f, 0.0f});
    c.position.push_back(glm::vec3(0.0f));
    c.texel.push_back(std::uint32_t(t));
    c.valid.push_back(1);
  }
  return c;
}

Status writeBake(const relight::RelightResult& r, const std::filesystem::path& dir, output::ExrOptions o = {}) {
  const caches::LightmapCaches lm = flatCaches(r.width, r.height);
  const caches::LightmapCaches fine = flatCaches(r.direct_width, r.direct_height);
  auto w = output::writeLightmapExrs(r, lm, dir.string(), o, r.directIsFiner() ? &fine : nullptr);
  return w ? Status{} : w.status();
}

// --- Crafted bake outputs (issue 44: `lightlink render` segfaulted on a crafted grid.raw) ---

// A grid.raw header (docs/outputs.md) followed by `payload`.
struct RawGrid {
  std::uint32_t bands = 1;
  std::uint32_t dims[3] = {2, 2, 2};
  float origin[3] = {0.0f, 0.0f, 0.0f};
  float spacing = 1.0f;
  std::string bytes(const std::string& payload) const {
    std::string out("LLGRID01", 8);
    auto put = [&](const void* p, std::size_t n) { out.append(static_cast<const char*>(p), n); };
    const std::uint64_t version = 1;
    put(&version, 8);
    put(&bands, 4);
    put(dims, 12);
    put(origin, 12);
    put(&spacing, 4);
    return out + payload;
  }
  // A payload of exactly the size the header implies (all SH 0.5, all points valid).
  std::string payload(std::size_t points) const {
    std::string p;
    const float v = 0.5f;
    for (std::size_t i = 0; i < points * 3 * bands * bands; ++i) p.append(reinterpret_cast<const char*>(&v), 4);
    return p + std::string(points, '\1');
  }
};

// A bake directory with a valid 2x2 one-band lightmap and the given grid.raw bytes.
class CraftedBake {
 public:
  explicit CraftedBake(const std::string& grid_raw) {
    relight::RelightResult r;
    r.bands = 1;
    r.width = r.height = 2;
    r.lightmap_sh.assign(4 * 3, 1.0f);
    r.direct.assign(4, glm::vec3(0.1f));
    r.texel_valid.assign(4, 1);
    const Status written = writeBake(r, dir_.path());
    EXPECT_TRUE(written) << written.toString();
    testing::writeFile(dir_ / "grid.raw", grid_raw);
  }
  std::string dir() const { return dir_.path().string(); }

 private:
  testing::TempDir dir_;
};

// Loads the bake and, if it loads, samples the grid as `render` does; the crafted grid must
// be rejected at load with a message naming `field`.
void expectGridRejected(const std::string& grid_raw, const std::string& field) {
  const CraftedBake bake(grid_raw);
  auto b = loadBakedLighting(bake.dir());
  if (b) {
    glm::vec3 e;
    for (const glm::vec3 p : {glm::vec3(0.5f), glm::vec3(-3.0f), glm::vec3(1e30f)}) (void)b->sampleGrid(p, {0, 1, 0}, e);
  }
  ASSERT_FALSE(b) << "a grid.raw with a bad " << field << " was accepted";
  EXPECT_EQ(b.status().code(), Code::kInvalidInput) << b.status().toString();
  EXPECT_NE(b.status().message().find("grid.raw"), std::string::npos) << b.status().message();
  EXPECT_NE(b.status().message().find(field), std::string::npos) << b.status().message();
}

TEST(BakedLightingFile, ValidGridLoads) {
  const RawGrid g;
  const CraftedBake bake(g.bytes(g.payload(8)));
  auto b = loadBakedLighting(bake.dir());
  ASSERT_TRUE(b) << b.status().toString();
  ASSERT_TRUE(b->has_grid);
  glm::vec3 e;
  EXPECT_TRUE(b->sampleGrid(glm::vec3(0.5f), {0, 1, 0}, e));
  EXPECT_TRUE(b->sampleGrid(glm::vec3(1e30f), {0, 1, 0}, e));  // far outside: the edge point
  EXPECT_FALSE(b->sampleGrid(glm::vec3(std::numeric_limits<float>::quiet_NaN()), {0, 1, 0}, e));
}

// The crash: dims whose product wraps around 2^64 to 11716 points, so the old size check
// passed, a file of 11716 points was read, and each dim became a negative int: render's
// trilinear lookup then indexed billions of points past the grid.
TEST(BakedLightingFile, GridDimsWhoseProductOverflowsAreRejected) {
  RawGrid g;
  g.dims[0] = 3197508789u;
  g.dims[1] = 3355758485u;
  g.dims[2] = 659735396u;
  ASSERT_EQ(std::uint64_t(g.dims[0]) * g.dims[1] * g.dims[2], 11716u);  // wraps (mod 2^64)
  expectGridRejected(g.bytes(g.payload(11716)), "dims");
}

TEST(BakedLightingFile, GridHeaderValuesAreChecked) {
  const float nan = std::numeric_limits<float>::quiet_NaN(), inf = std::numeric_limits<float>::infinity();
  RawGrid g;
  g.spacing = nan;
  expectGridRejected(g.bytes(g.payload(8)), "spacing");
  g.spacing = 0.0f;
  expectGridRejected(g.bytes(g.payload(8)), "spacing");
  g.spacing = -1.0f;
  expectGridRejected(g.bytes(g.payload(8)), "spacing");
  g = RawGrid{};
  g.origin[1] = inf;
  expectGridRejected(g.bytes(g.payload(8)), "origin");
  g = RawGrid{};
  g.dims[2] = 0;
  expectGridRejected(g.bytes(""), "dims");
  g = RawGrid{};
  g.bands = 2;  // the lightmap has 1
  expectGridRejected(g.bytes(g.payload(8)), "bands");
  g.bands = 9;
  expectGridRejected(g.bytes(g.payload(8)), "bands");
}

// Sizes are checked against the file length before anything is allocated: a 48-byte file
// claiming 2^24 points is rejected at once (it used to allocate 200 MB first).
TEST(BakedLightingFile, GridSizeMustMatchTheFileLength) {
  RawGrid g;
  expectGridRejected(g.bytes(g.payload(8).substr(0, 50)), "bytes");  // truncated payload
  expectGridRejected(g.bytes(g.payload(8) + "x"), "bytes");           // trailing garbage
  expectGridRejected(g.bytes("").substr(0, 30), "header");            // truncated header
  g.dims[0] = 1u << 24;
  g.dims[1] = g.dims[2] = 1;
  expectGridRejected(g.bytes(""), "bytes");
  g.dims[0] = g.dims[1] = g.dims[2] = 1u << 20;  // 2^60 points
  expectGridRejected(g.bytes(""), "dims");
}

TEST(BakedLightingFile, GridValuesMustBeFinite) {
  const RawGrid g;
  std::string payload = g.payload(8);
  const float nan = std::numeric_limits<float>::quiet_NaN();
  std::memcpy(payload.data() + 4 * 5, &nan, 4);
  expectGridRejected(g.bytes(payload), "not finite");
  payload = g.payload(8);
  payload[payload.size() - 1] = 7;  // a validity byte that is neither 0 nor 1
  expectGridRejected(g.bytes(payload), "valid");
}

// The lightmap reader: a window larger than the limit and non-finite values are rejected,
// naming what is wrong (the limit is 16384^2 texels in `render`; 3 here).
TEST(BakedLightingFile, LightmapSizeAndValuesAreChecked) {
  testing::TempDir dir;
  relight::RelightResult r;
  r.bands = 1;
  r.width = r.height = 2;
  r.lightmap_sh.assign(4 * 3, 1.0f);
  r.direct.assign(4, glm::vec3(0.1f));
  r.texel_valid.assign(4, 1);
  output::ExrOptions float_exr;
  float_exr.half = false;
  ASSERT_TRUE(writeBake(r, dir.path(), float_exr));
  BakedLighting ok;
  ASSERT_TRUE(readLightmapExrs(dir.path().string(), ok)) << "a valid 2x2 lightmap";
  BakedLighting small;
  const Status too_big = readLightmapExrs(dir.path().string(), small, 3);
  EXPECT_EQ(too_big.code(), Code::kInvalidInput);
  EXPECT_NE(too_big.message().find("data window 2x2 is out of range"), std::string::npos) << too_big.message();
  r.lightmap_sh[1] = std::numeric_limits<float>::quiet_NaN();
  ASSERT_TRUE(writeBake(r, dir.path(), float_exr));
  BakedLighting nan;
  const Status s = readLightmapExrs(dir.path().string(), nan);
  EXPECT_EQ(s.code(), Code::kInvalidInput);
  EXPECT_NE(s.message().find("is not finite"), std::string::npos) << s.message();
}

// Layout 1 (one lightmap.exr of L00.R... layers) and an unknown layout are refused with a
// message that says which and what to do.
TEST(BakedLightingFile, OldAndUnknownLayoutsAreRejected) {
  testing::TempDir dir;
  relight::RelightResult r;
  r.bands = 1;
  r.width = r.height = 2;
  r.lightmap_sh.assign(4 * 3, 1.0f);
  r.direct.assign(4, glm::vec3(0.1f));
  r.texel_valid.assign(4, 1);
  ASSERT_TRUE(writeBake(r, dir.path()));
  // A layout-1 file: the L00.R channel and lightlink.bands, no lightlink.layout.
  const std::string old = (dir / "old.exr").string();
  {
    Imf::Header h(2, 2);
    h.channels().insert("L00.R", Imf::Channel(Imf::FLOAT));
    h.insert("lightlink.bands", Imf::IntAttribute(1));
    std::vector<float> px(4, 1.0f);
    Imf::FrameBuffer fb;
    fb.insert("L00.R", Imf::Slice(Imf::FLOAT, reinterpret_cast<char*>(px.data()), 4, 8));
    Imf::OutputFile f(old.c_str(), h);
    f.setFrameBuffer(fb);
    f.writePixels(2);
  }
  ExrImage img;
  const Status s = readLightlinkExr(old, img);
  EXPECT_EQ(s.code(), Code::kInvalidInput);
  EXPECT_NE(s.message().find("layout 1"), std::string::npos) << s.message();
  EXPECT_NE(s.message().find("bake again"), std::string::npos) << s.message();
  // A whole layout-1 bake directory is refused by name.
  std::filesystem::rename(old, dir / "lightmap.exr");
  for (const char* f : {"lightmap_L00.exr", "irradiance.exr"}) std::filesystem::remove(dir / f);
  auto b = loadBakedLighting(dir.path().string());
  ASSERT_FALSE(b);
  EXPECT_NE(b.status().message().find("layout 1"), std::string::npos) << b.status().message();
  // A layout from a newer lightlink.
  const std::string future = (dir / "future.exr").string();
  {
    Imf::Header h(2, 2);
    h.channels().insert("Y", Imf::Channel(Imf::FLOAT));
    h.insert("lightlink.layout", Imf::IntAttribute(output::kExrLayout + 1));
    std::vector<float> px(4, 1.0f);
    Imf::FrameBuffer fb;
    fb.insert("Y", Imf::Slice(Imf::FLOAT, reinterpret_cast<char*>(px.data()), 4, 8));
    Imf::OutputFile f(future.c_str(), h);
    f.setFrameBuffer(fb);
    f.writePixels(2);
  }
  const Status t = readLightlinkExr(future, img);
  EXPECT_EQ(t.code(), Code::kInvalidInput);
  EXPECT_NE(t.message().find("lightlink.layout " + std::to_string(output::kExrLayout + 1)), std::string::npos)
      << t.message();
}

// Every encoding read back by the viewer samples what the in-memory result gives at texel
// centres: L2 and L1 the SH of their bands plus direct, L0 the irradiance map.
TEST(BakedLightingFile, EachEncodingReadsBackAsTheResultEvaluates) {
  relight::RelightResult r;
  r.bands = 3;
  r.width = 4;
  r.height = 2;
  const std::size_t texels = 8;
  r.lightmap_sh.resize(texels * 27);
  for (std::size_t k = 0; k < r.lightmap_sh.size(); ++k) r.lightmap_sh[k] = 0.2f + 0.1f * std::sin(float(k));
  for (std::size_t t = 0; t < texels; ++t) {
    r.direct.push_back(glm::vec3(0.5f * float(t), 0.25f, 1.0f));
    r.texel_valid.push_back(1);
  }
  const glm::vec3 up(0.0f, 1.0f, 0.0f);
  for (const output::Encoding enc : {output::Encoding::kL0, output::Encoding::kL1, output::Encoding::kL2}) {
    testing::TempDir dir;
    ASSERT_TRUE(writeBake(r, dir.path(), {.half = false, .encoding = enc}));
    auto b = loadBakedLighting(dir.path().string());
    ASSERT_TRUE(b) << b.status().toString();
    const int bands = output::lightmapBands(enc, r.bands);
    EXPECT_EQ(b->bands, bands);
    for (std::size_t t = 0; t < texels; ++t) {
      const glm::vec2 uv((float(t % 4) + 0.5f) / 4.0f, (float(t / 4) + 0.5f) / 2.0f);
      glm::vec3 e;
      ASSERT_TRUE(b->sampleLightmap(uv, up, e));
      const int eval_bands = bands == 0 ? r.bands : bands;  // L0 holds the full result's evaluation
      for (int ch = 0; ch < 3; ++ch) {
        const float want = sh::irradiance(eval_bands, r.lightmap_sh.data() + t * 27 + std::size_t(ch) * 9, up) +
                           r.direct[t][ch];
        EXPECT_NEAR(e[ch], want, 1e-5f * std::max(1.0f, want)) << output::encodingName(enc) << " texel " << t;
      }
    }
  }
}

// A finer direct layer travels as direct.exr at its own size (lightlink.direct_scale 2)
// and is sampled at its own resolution: a direct step inside one lightmap texel survives.
TEST(BakedLightingFile, FinerDirectLayerLoadsFromItsOwnFile) {
  relight::RelightResult r;
  r.bands = 1;
  r.width = r.height = 2;
  r.lightmap_sh.assign(4 * 3, 0.0f);
  r.texel_valid.assign(4, 1);
  r.direct_width = r.direct_height = 4;
  r.direct.assign(16, glm::vec3(0.0f));
  r.direct_valid.assign(16, 1);
  for (int y = 0; y < 4; ++y) r.direct[std::size_t(y) * 4 + 3] = glm::vec3(8.0f);  // the last column lit
  testing::TempDir dir;
  ASSERT_TRUE(writeBake(r, dir.path()));
  auto b = loadBakedLighting(dir.path().string());
  ASSERT_TRUE(b) << b.status().toString();
  EXPECT_EQ(b->direct_scale, 2);
  EXPECT_EQ(b->direct_width, 4);
  glm::vec3 e;
  ASSERT_TRUE(b->sampleLightmap({0.875f, 0.5f}, {0, 1, 0}, e));
  EXPECT_FLOAT_EQ(e.x, 8.0f);
  ASSERT_TRUE(b->sampleLightmap({0.625f, 0.5f}, {0, 1, 0}, e));
  EXPECT_FLOAT_EQ(e.x, 0.0f);  // same lightmap texel, a direct texel to the left: dark

  // Without its direct.exr the bake is refused, naming the file.
  std::filesystem::remove(dir.path() / "direct.exr");
  auto missing = loadBakedLighting(dir.path().string());
  ASSERT_FALSE(missing);
  EXPECT_NE(missing.status().message().find("direct.exr"), std::string::npos) << missing.status().message();
}

}  // namespace
}  // namespace lightlink::viewer
