#include "clients/viewer/baked_lighting.h"

#include <array>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <limits>
#include <numbers>
#include <string>

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
  EXPECT_NE(b.status().message().find("lightmap.exr"), std::string::npos) << b.status().message();
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

// A bake directory with a valid 2x2 one-band lightmap.exr and the given grid.raw bytes.
class CraftedBake {
 public:
  explicit CraftedBake(const std::string& grid_raw) {
    relight::RelightResult r;
    r.bands = 1;
    r.width = r.height = 2;
    r.lightmap_sh.assign(4 * 3, 1.0f);
    r.direct.assign(4, glm::vec3(0.1f));
    r.texel_valid.assign(4, 1);
    auto written = output::writeLightmapExr(r, (dir_ / "lightmap.exr").string());
    EXPECT_TRUE(written) << written.status().toString();
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
  const std::string path = (dir / "lightmap.exr").string();
  ASSERT_TRUE(output::writeLightmapExr(r, path, float_exr));
  BakedLighting ok;
  ASSERT_TRUE(readLightmapExr(path, ok)) << "a valid 2x2 lightmap";
  BakedLighting small;
  const Status too_big = readLightmapExr(path, small, 3);
  EXPECT_EQ(too_big.code(), Code::kInvalidInput);
  EXPECT_NE(too_big.message().find("data window 2x2 is out of range"), std::string::npos) << too_big.message();
  r.lightmap_sh[7] = std::numeric_limits<float>::quiet_NaN();
  ASSERT_TRUE(output::writeLightmapExr(r, path, float_exr));
  BakedLighting nan;
  const Status s = readLightmapExr(path, nan);
  EXPECT_EQ(s.code(), Code::kInvalidInput);
  EXPECT_NE(s.message().find("is not finite"), std::string::npos) << s.message();
}

// A finer direct layer travels as direct.exr beside lightmap.exr (lightlink.direct_scale 2)
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
  ASSERT_TRUE(output::writeLightmapExr(r, (dir.path() / "lightmap.exr").string()));
  ASSERT_TRUE(output::writeDirectExr(r, (dir.path() / "direct.exr").string()));
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
