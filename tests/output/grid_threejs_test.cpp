// The three.js grid export: unpacking the texture the way three.js's shader does
// (lightprobes_pars_fragment: sub-volume t of probe z at slice t * (nz + 2) + 1 + z,
// c_k.rgb = floats 3k..3k+2 of the 28 packed four per texel) gives back every probe's
// lightlink coefficients bit-exactly, padding slices copy the edge slices, and the volume
// puts each lightlink grid point at the centre of its three.js cell. three.js's own code
// reads the bake's file in tests/node/threejs_grid.mjs.
#include <gtest/gtest.h>

#include <cstring>
#include <fstream>
#include <random>

#include <nlohmann/json.hpp>

#include "core/output/grid_threejs.h"
#include "core/sh/sh.h"
#include "tests/common/testing.h"

namespace lightlink::output {
namespace {

struct Synthetic {
  relight::RelightResult result;
  caches::GridCaches grid;
};

Synthetic synthetic(int bands, glm::ivec3 dims) {
  Synthetic s;
  s.grid.dims = dims;
  s.grid.origin = {-1.0f, 0.25f, 3.0f};
  s.grid.spacing_m = 0.5f;
  const std::size_t n = std::size_t(dims.x) * dims.y * dims.z;
  s.grid.position.resize(n);
  s.grid.valid.assign(n, 1);
  s.result.bands = bands;
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  s.result.grid_sh.resize(n * 3 * bands * bands);
  for (float& v : s.result.grid_sh) v = u(rng);
  return s;
}

// What three.js's shader reads for probe (x, y, z): 9 RGB coefficients.
std::array<glm::vec3, 9> unpack(const ThreeJsGrid& g, int x, int y, int z) {
  const glm::ivec3 r = g.resolution;
  float packed[28];
  for (int t = 0; t < 7; ++t) {
    const std::size_t slice = std::size_t(t) * (r.z + 2) + 1 + z;
    const std::size_t texel = (slice * r.y + y) * r.x + x;
    std::memcpy(packed + 4 * t, &g.rgba[texel * 4], 4 * sizeof(float));
  }
  std::array<glm::vec3, 9> c;
  for (int k = 0; k < 9; ++k) c[k] = {packed[3 * k], packed[3 * k + 1], packed[3 * k + 2]};
  return c;
}

TEST(ThreeJsGrid, UnpacksToLightlinksCoefficientsForEveryBandCount) {
  for (int bands : {1, 2, 3, 4}) {
    SCOPED_TRACE(bands);
    const Synthetic s = synthetic(bands, {3, 2, 4});
    Expected<ThreeJsGrid> g = threeJsGrid(s.result, s.grid);
    ASSERT_TRUE(g) << g.status().toString();
    EXPECT_EQ(g->resolution, s.grid.dims);
    EXPECT_EQ(g->depth, 7 * (4 + 2));
    ASSERT_EQ(g->rgba.size(), std::size_t(3 * 2 * g->depth * 4));
    const int nc = bands * bands;
    for (int z = 0; z < 4; ++z)
      for (int y = 0; y < 2; ++y)
        for (int x = 0; x < 3; ++x) {
          const std::size_t e = (std::size_t(z) * 2 + y) * 3 + x;
          const std::array<glm::vec3, 9> c = unpack(*g, x, y, z);
          for (int i = 0; i < 9; ++i)
            for (int ch = 0; ch < 3; ++ch) {
              const float want = i < nc ? s.result.grid_sh[e * 3 * nc + std::size_t(ch) * nc + i] : 0.0f;
              ASSERT_EQ(c[i][ch], want) << "probe " << x << "," << y << "," << z << " coefficient " << i;
            }
          // Same irradiance for any direction (band 3, dropped, has A_3 = 0).
          sh::ShRgb<3> three{};
          for (int i = 0; i < 9; ++i)
            for (int ch = 0; ch < 3; ++ch) three.c[ch][i] = c[i][ch];
          sh::ShRgb<4> ll{};
          for (int i = 0; i < nc; ++i)
            for (int ch = 0; ch < 3; ++ch) ll.c[ch][i] = s.result.grid_sh[e * 3 * nc + std::size_t(ch) * nc + i];
          const glm::vec3 n = glm::normalize(glm::vec3(0.3f, -0.8f, 0.5f));
          const glm::vec3 a = sh::irradiance(three, n), b = sh::irradiance(ll, n);
          for (int ch = 0; ch < 3; ++ch) EXPECT_NEAR(a[ch], b[ch], 1e-5f * (1.0f + std::abs(b[ch])));
        }
  }
}

TEST(ThreeJsGrid, PaddingCopiesTheEdgeSlicesAndTheVolumeCentresEachProbeInItsCell) {
  const Synthetic s = synthetic(3, {2, 3, 5});
  Expected<ThreeJsGrid> g = threeJsGrid(s.result, s.grid);
  ASSERT_TRUE(g) << g.status().toString();
  const std::size_t slice = 2 * 3 * 4;  // floats per slice
  for (int t = 0; t < 7; ++t) {
    const std::size_t base = std::size_t(t) * (5 + 2);
    auto at = [&](std::size_t sl) { return std::vector<float>(g->rgba.begin() + sl * slice, g->rgba.begin() + (sl + 1) * slice); };
    EXPECT_EQ(at(base), at(base + 1)) << "sub-volume " << t;
    EXPECT_EQ(at(base + 6), at(base + 5)) << "sub-volume " << t;
  }
  // three.js: probe i at min + (i + 0.5) * (max - min) / resolution (getProbePosition).
  for (int a = 0; a < 3; ++a) {
    const float cell = (g->max[a] - g->min[a]) / float(g->resolution[a]);
    EXPECT_NEAR(cell, s.grid.spacing_m, 1e-6f);
    EXPECT_NEAR(g->min[a] + 0.5f * cell, s.grid.origin[a], 1e-6f);
    EXPECT_NEAR(g->min[a] + (float(g->resolution[a] - 1) + 0.5f) * cell,
                s.grid.origin[a] + s.grid.spacing_m * float(s.grid.dims[a] - 1), 1e-5f);
  }
}

TEST(ThreeJsGrid, WritesTheJsonAndTheTextureAndRefusesAResultWithoutAGrid) {
  const Synthetic s = synthetic(3, {2, 2, 2});
  lightlink::testing::TempDir tmp;
  ASSERT_TRUE(writeThreeJsGrid(s.result, s.grid, (tmp / "grid_threejs.json").string(), "grid_threejs.bin"));
  std::ifstream in(tmp / "grid_threejs.json");
  const nlohmann::json j = nlohmann::json::parse(in);
  EXPECT_EQ(j["texture"]["data"], "grid_threejs.bin");
  EXPECT_EQ(j["texture"]["depth"].get<int>(), 28);
  EXPECT_EQ(j["resolution"], nlohmann::json::array({2, 2, 2}));
  EXPECT_EQ(std::filesystem::file_size(tmp / "grid_threejs.bin"), std::uintmax_t(2 * 2 * 28 * 4 * 4));

  relight::RelightResult empty;
  empty.bands = 3;
  const Status bad = writeThreeJsGrid(empty, s.grid, (tmp / "x.json").string(), "x.bin");
  EXPECT_EQ(bad.code(), Code::kInvalidInput) << bad.toString();
  EXPECT_NE(bad.toString().find("no grid relit"), std::string::npos) << bad.toString();
}

}  // namespace
}  // namespace lightlink::output
