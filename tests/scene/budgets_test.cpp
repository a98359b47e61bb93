// Loader budgets (scene::LoadOptions, docs/cli.md "Limits"): files that claim far more work
// than their size are refused from their headers and node graph, before the work, with
// Code::kResourceExhausted naming the limit and the value.
#include <fstream>
#include <sstream>
#include <string>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "core/scene/load.h"
#include "tests/common/hostile_scenes.h"
#include "tests/common/testing.h"

namespace lightlink::testing {
namespace {

// Peak resident memory of this process so far (VmHWM), in bytes.
std::uint64_t peakRss() {
  std::ifstream status("/proc/self/status");
  std::string line;
  while (std::getline(status, line))
    if (line.rfind("VmHWM:", 0) == 0) return std::stoull(line.substr(6)) * 1024;
  return 0;
}

TEST(LoadBudgets, DecompressionBombIsRefusedFromItsHeader) {
  TempDir dir;
  // 144 Mpixels of zeros in ~150 KB: 576 MB as stb decodes it, another 576 MB as a texture.
  const std::string png = zeroPng(12000, 12000);
  EXPECT_LT(png.size(), 400u * 1024);
  const std::string path = writeFile(dir / "bomb.gltf", texturedQuadGltf(png));
  const std::uint64_t before = peakRss();
  auto scene = scene::loadGltf(path);
  ASSERT_FALSE(scene);
  EXPECT_EQ(scene.status().code(), Code::kResourceExhausted) << scene.status().toString();
  EXPECT_NE(scene.status().message().find("12000x12000"), std::string::npos) << scene.status().message();
  EXPECT_NE(scene.status().message().find("max_image_pixels"), std::string::npos) << scene.status().message();
  // Nothing was inflated: the peak grew by far less than one decoded copy.
  EXPECT_LT(peakRss() - before, std::uint64_t(100) << 20);

  // Under the limit the same kind of image decodes as before.
  auto small = scene::loadGltf(writeFile(dir / "small.gltf", texturedQuadGltf(zeroPng(64, 32))));
  ASSERT_TRUE(small) << small.status().toString();
  ASSERT_EQ(small->textures.size(), 1u);
  EXPECT_EQ(small->textures[0].width, 64);
  EXPECT_EQ(small->textures[0].height, 32);
  // And a lowered limit refuses it, naming the value.
  scene::LoadOptions tight;
  tight.max_image_pixels = 64 * 31;
  auto refused = scene::loadGltf(dir / "small.gltf", tight);
  ASSERT_FALSE(refused);
  EXPECT_EQ(refused.status().code(), Code::kResourceExhausted);
  EXPECT_NE(refused.status().message().find("64x32 = 2048 pixels"), std::string::npos) << refused.status().message();
}

TEST(LoadBudgets, InstancingBombIsRefusedBeforeFlattening) {
  TempDir dir;
  // 2,000 triangles placed by 10,001 nodes: 20,002,000 triangles from a ~500 KB file.
  const std::string text = instancedGridGltf(2000, 10001);
  EXPECT_LT(text.size(), std::size_t(1) << 20);
  const std::string path = writeFile(dir / "instances.gltf", text);
  const std::uint64_t before = peakRss();
  auto scene = scene::loadGltf(path);
  ASSERT_FALSE(scene);
  EXPECT_EQ(scene.status().code(), Code::kResourceExhausted) << scene.status().toString();
  EXPECT_NE(scene.status().message().find("20002000 triangles"), std::string::npos) << scene.status().message();
  EXPECT_NE(scene.status().message().find("max_triangles"), std::string::npos) << scene.status().message();
  EXPECT_LT(peakRss() - before, std::uint64_t(200) << 20);

  // The count is exact: at the limit the scene loads, one triangle over it does not.
  const std::string few = writeFile(dir / "few.gltf", instancedGridGltf(100, 30));
  scene::LoadOptions o;
  o.max_triangles = 3000;
  auto at = scene::loadGltf(few, o);
  ASSERT_TRUE(at) << at.status().toString();
  EXPECT_EQ(at->triangleCount(), 3000u);
  o.max_triangles = 2999;
  auto over = scene::loadGltf(few, o);
  ASSERT_FALSE(over);
  EXPECT_EQ(over.status().code(), Code::kResourceExhausted);
}

TEST(LoadBudgets, PlacedLightsAreCapped) {
  TempDir dir;
  nlohmann::json j = nlohmann::json::parse(instancedGridGltf(2, 1));
  j["extensionsUsed"] = {"KHR_lights_punctual"};
  j["extensions"]["KHR_lights_punctual"]["lights"] = {{{"type", "point"}, {"intensity", 1.0}}};
  for (int i = 0; i < 12; ++i) {
    j["nodes"].push_back({{"translation", {0.0, 1.0 + i, 0.0}}, {"extensions", {{"KHR_lights_punctual", {{"light", 0}}}}}});
    j["scenes"][0]["nodes"].push_back(i + 1);
  }
  const std::string path = writeFile(dir / "lights.gltf", j.dump());
  auto all = scene::loadGltf(path);
  ASSERT_TRUE(all) << all.status().toString();
  EXPECT_EQ(all->lights.size(), 12u);
  scene::LoadOptions o;
  o.max_lights = 11;
  auto capped = scene::loadGltf(path, o);
  ASSERT_FALSE(capped);
  EXPECT_EQ(capped.status().code(), Code::kResourceExhausted);
  EXPECT_NE(capped.status().message().find("max_lights"), std::string::npos) << capped.status().message();
}

}  // namespace
}  // namespace lightlink::testing
