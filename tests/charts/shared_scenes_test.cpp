// Every shared scene through unwrap() with default options: a valid atlas by the oracle
// (no chart overlap, gutter kept, no flips, stretch within the limit); scenes whose
// static meshes all carry TEXCOORD_1 keep it and get it checked instead.
#include <gtest/gtest.h>

#include <cstdio>

#include "core/charts/unwrap.h"
#include "core/scene/load.h"
#include "tests/charts/atlas_oracle.h"
#include "tests/common/testing.h"

namespace lightlink::charts {
namespace {

namespace fs = std::filesystem;

class SharedScene : public ::testing::TestWithParam<std::pair<const char*, const char*>> {};

TEST_P(SharedScene, DefaultUnwrapIsValid) {
  const fs::path dir = lightlink::testing::sharedScenesDir();
  if (dir.empty()) GTEST_SKIP() << "shared scenes not found";
  const fs::path path = dir / GetParam().first / GetParam().second;
  Expected<scene::Scene> scene = scene::loadGltf(path.string(), {.load_textures = false});
  ASSERT_TRUE(scene) << scene.status().toString();
  const UnwrapOptions options;
  Expected<UnwrapResult> result = unwrap(*scene, options);
  ASSERT_TRUE(result) << result.status().toString();
  const UnwrapReport& report = result->report;
  std::printf("%s\n%s", GetParam().first, report.toText().c_str());
  const testing::OracleResult oracle = testing::checkWithOracle(*scene, result->atlas);
  if (!report.generated) {
    // Kept: the library's check and the oracle agree on whether the uv1 overlaps.
    EXPECT_EQ(report.overlaps > 0, oracle.center_overlaps > 0);
    EXPECT_EQ(report.out_of_range, oracle.out_of_range);
    return;
  }
  EXPECT_EQ(oracle.chart_overlap_texels, 0u) << oracle.first_problem;
  EXPECT_EQ(oracle.center_overlaps, 0u) << oracle.first_problem;
  EXPECT_EQ(oracle.gutter_violations, 0u) << oracle.first_problem;
  EXPECT_EQ(oracle.flipped, 0u) << oracle.first_problem;
  EXPECT_EQ(oracle.out_of_range, 0u);
  EXPECT_EQ(report.overlaps, 0u);
  EXPECT_EQ(report.gutter_violations, 0u);
  EXPECT_LE(report.max_area_stretch, options.max_stretch * 1.001);
  EXPECT_EQ(report.resolution, options.target_resolution);
  EXPECT_GT(report.utilisation, 0.4);
}

INSTANTIATE_TEST_SUITE_P(
    All, SharedScene,
    ::testing::Values(std::pair{"cornell_box_original_gltf", "CornellBox-Original.gltf"},
                      std::pair{"cornell_box_vinc3r_lightmapuv", "cornellBox-2.80-Eevee-gltf.gltf"},
                      std::pair{"khronos_EmissiveStrengthTest", "EmissiveStrengthTest.gltf"},
                      std::pair{"khronos_LightsPunctualLamp", "LightsPunctualLamp.gltf"},
                      std::pair{"khronos_MultiUVTest", "MultiUVTest.gltf"},
                      std::pair{"revelry_ShadowsSpot", "shadows-spot.gltf"},
                      std::pair{"revelry_ShadowsDirectional", "shadows-directional.gltf"},
                      std::pair{"sauerbraten_zdm2_level_gltf", "zdm2.glb"}),
    [](const auto& info) { return std::string(info.param.first); });

}  // namespace
}  // namespace lightlink::charts
