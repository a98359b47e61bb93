// The LIGHTLINK_lighting description: what bake wrote and nothing else, the grid's placement
// as the grid writers state it, the SH layers in index order.
#include <gtest/gtest.h>

#include "core/output/lighting_description.h"

namespace lightlink::output {
namespace {

TEST(LightingDescription, NamesWhatWasWrittenAndOnlyThat) {
  relight::RelightResult result;
  result.bands = 2;
  result.width = 64;
  result.height = 32;
  result.version = 5;
  LightingFiles files = LightingFiles::fromWritten(
      {"irradiance.exr", "lightmap_L00.exr", "lightmap_L1m1.exr", "lightmap_L10.exr", "lightmap_L11.exr",
       "direct.exr", "valid.exr", "lightmap.png"},
      "l1");
  files.irradiance.clear();
  nlohmann::json j = describeLighting(result, nullptr, files);
  EXPECT_EQ(j["version"], 2);
  EXPECT_EQ(j["encoding"], "l1");
  EXPECT_EQ(j["light_set_version"], 5);
  EXPECT_EQ(j["lightmap"]["sh"], nlohmann::json::array({"lightmap_L00.exr", "lightmap_L1m1.exr", "lightmap_L10.exr",
                                                        "lightmap_L11.exr"}));
  EXPECT_EQ(j["lightmap"]["valid"], "valid.exr");
  EXPECT_EQ(j["lightmap"]["texCoord"], 1);
  EXPECT_EQ(j["lightmap"]["width"], 64);
  EXPECT_EQ(j["lightmap"]["direct"]["uri"], "direct.exr");
  EXPECT_EQ(j["units"]["irradiance"], "lux per linear RGB channel");
  EXPECT_FALSE(j.contains("irradiance"));
  EXPECT_FALSE(j.contains("grid"));

  caches::GridCaches grid;
  grid.origin = {1.0f, 2.0f, 3.0f};
  grid.spacing_m = 0.25f;
  grid.dims = {2, 1, 3};
  grid.position.resize(6);
  grid.valid = {1, 0, 1, 1, 1, 0};
  result.direct_width = 128;
  result.direct_height = 64;
  files.direct_valid = "direct_valid.exr";
  files.irradiance = "irradiance.exr";
  files.grid_json = "grid.json";
  files.grid_threejs = "grid_threejs.json";
  j = describeLighting(result, &grid, files);
  EXPECT_EQ(j["lightmap"]["direct"]["uri"], "direct.exr");
  EXPECT_EQ(j["lightmap"]["direct"]["width"], 128);
  EXPECT_EQ(j["irradiance"]["uri"], "irradiance.exr");
  EXPECT_EQ(j["irradiance"]["bound_by"], "MOZ_lightmap");
  EXPECT_EQ(j["grid"]["origin_m"], nlohmann::json::array({1.0, 2.0, 3.0}));
  EXPECT_EQ(j["grid"]["spacing_m"], 0.25);
  EXPECT_EQ(j["grid"]["dims"], nlohmann::json::array({2, 1, 3}));
  EXPECT_EQ(j["grid"]["valid_count"], 4);
  EXPECT_EQ(j["grid"]["json"]["uri"], "grid.json");
  EXPECT_EQ(j["grid"]["threejs"]["uri"], "grid_threejs.json");
  EXPECT_FALSE(j["grid"].contains("exr"));
  EXPECT_FALSE(j["grid"].contains("raw"));
}

}  // namespace
}  // namespace lightlink::output
