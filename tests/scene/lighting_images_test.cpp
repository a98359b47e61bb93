// Only the images that feed lighting are decoded (core/scene/lighting_images.h), each once;
// a missing, empty or undecodable one is a warning naming it, and the material's factor is
// used (issue 45, robust ingest).
#include <algorithm>
#include <filesystem>
#include <string>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "core/scene/lighting_images.h"
#include "core/scene/load.h"
#include "tests/common/hostile_scenes.h"
#include "tests/common/testing.h"

namespace lightlink::testing {
namespace {

// The textured quad of hostile_scenes.h with external images: images[0] is the base colour
// (`albedo.png`), images[1] the normal map (`normal.png`), images[2] named by no texture.
nlohmann::json quadWithNormalMap() {
  nlohmann::json j = nlohmann::json::parse(texturedQuadGltf(zeroPng(4, 2)));
  j["images"] = {{{"uri", "albedo.png"}}, {{"uri", "normal.png"}}, {{"uri", "unused.png"}}};
  j["textures"] = {{{"source", 0}}, {{"source", 1}}};
  j["materials"][0]["normalTexture"] = {{"index", 1}};
  return j;
}

std::size_t warningsMentioning(const scene::Scene& s, const std::string& what) {
  return static_cast<std::size_t>(std::count_if(s.warnings.begin(), s.warnings.end(), [&](const std::string& w) {
    return w.find(what) != std::string::npos;
  }));
}

std::string allWarnings(const scene::Scene& s) {
  std::string out;
  for (const std::string& w : s.warnings) out += w + "\n";
  return out;
}

TEST(LightingImages, NormalMapsAndUnusedImagesAreNeitherDecodedNorWarnedAbout) {
  TempDir dir;
  writeFile(dir / "albedo.png", zeroPng(4, 2));
  writeFile(dir / "normal.png", "not a png at all");  // garbage: decoding it would warn
  writeFile(dir / "unused.png", "garbage too");
  const std::string path = writeFile(dir / "scene.gltf", quadWithNormalMap().dump());
  auto s = scene::loadGltf(path);
  ASSERT_TRUE(s) << s.status().toString();
  EXPECT_EQ(s->stats.images_decoded, 1u);
  EXPECT_EQ(s->stats.images_skipped, 2u);
  EXPECT_EQ(s->stats.image_bytes, 4u * 2 * 3);  // RGB: the material is opaque
  EXPECT_TRUE(s->warnings.empty()) << allWarnings(*s);
  ASSERT_EQ(s->textures.size(), 2u);
  EXPECT_EQ(s->textures[0].width, 4);
  EXPECT_EQ(s->textures[0].rgba8.size(), 4u * 2 * 3);
  EXPECT_EQ(s->textures[0].channels, 3);
  EXPECT_TRUE(s->textures[1].rgba8.empty());
  // The budgets bound what is decoded: a 64x64 normal map is over a limit of 8 pixels per
  // image, but it is never decoded; the 4x2 base colour is at the limit.
  writeFile(dir / "normal.png", zeroPng(64, 64));
  scene::LoadOptions tight;
  tight.max_image_pixels = 8;
  tight.max_image_bytes = 4 * 2 * 3;
  auto budgeted = scene::loadGltf(path, tight);
  ASSERT_TRUE(budgeted) << budgeted.status().toString();
  EXPECT_EQ(budgeted->stats.images_decoded, 1u);
  tight.max_image_pixels = 7;
  auto over = scene::loadGltf(path, tight);
  ASSERT_FALSE(over);
  EXPECT_EQ(over.status().code(), Code::kResourceExhausted);
  EXPECT_NE(over.status().message().find("image 0"), std::string::npos) << over.status().message();
  // They are not even read: missing, they are no warning either.
  std::filesystem::remove(dir / "normal.png");
  std::filesystem::remove(dir / "unused.png");
  auto again = scene::loadGltf(path);
  ASSERT_TRUE(again) << again.status().toString();
  EXPECT_TRUE(again->warnings.empty()) << allWarnings(*again);
  EXPECT_EQ(again->stats.images_decoded, 1u);
}

TEST(LightingImages, UndecodableMissingOrEmptyBaseColourIsAWarningAndTheFactorIsUsed) {
  for (const char* kind : {"garbage", "missing", "empty"}) {
    SCOPED_TRACE(kind);
    TempDir dir;
    if (std::string(kind) == "garbage") writeFile(dir / "albedo.png", "\x89PNG but not really");
    if (std::string(kind) == "empty") writeFile(dir / "albedo.png", "");
    writeFile(dir / "normal.png", zeroPng(2, 2));
    writeFile(dir / "unused.png", zeroPng(2, 2));
    const std::string path = writeFile(dir / "scene.gltf", quadWithNormalMap().dump());
    auto s = scene::loadGltf(path);
    ASSERT_TRUE(s) << s.status().toString();
    EXPECT_EQ(s->stats.images_decoded, 0u);
    // The texture that needed it is named, with its image and file.
    EXPECT_EQ(warningsMentioning(*s, "texture 0: image 0 'albedo.png' was not decoded; the material's factor is used"),
              1u)
        << allWarnings(*s);
    EXPECT_TRUE(s->textures[0].rgba8.empty());
    EXPECT_EQ(s->textures[0].sampleSrgb({0.5f, 0.5f}), glm::vec4(1.0f));  // factor alone
  }
}

TEST(LightingImages, AnImageSharedByTexturesIsDecodedOnce) {
  TempDir dir;
  writeFile(dir / "albedo.png", zeroPng(4, 2));
  nlohmann::json j = nlohmann::json::parse(texturedQuadGltf(zeroPng(4, 2)));
  j["images"] = {{{"uri", "albedo.png"}}};
  j["samplers"] = {{{"magFilter", 9728}}};
  j["textures"] = {{{"source", 0}}, {{"source", 0}, {"sampler", 0}}};
  j["materials"].push_back(j["materials"][0]);
  j["materials"][1]["pbrMetallicRoughness"]["baseColorTexture"]["index"] = 1;
  j["meshes"][0]["primitives"].push_back(j["meshes"][0]["primitives"][0]);
  j["meshes"][0]["primitives"][1]["material"] = 1;
  auto s = scene::loadGltf(writeFile(dir / "scene.gltf", j.dump()));
  ASSERT_TRUE(s) << s.status().toString();
  EXPECT_EQ(s->stats.images_decoded, 1u);
  ASSERT_EQ(s->textures.size(), 2u);
  EXPECT_EQ(s->textures[0].rgba8.size(), 24u);
  EXPECT_EQ(s->textures[1].rgba8.size(), 24u);
  EXPECT_TRUE(s->textures[1].nearest);
}

TEST(LightingImages, AlphaIsKeptOnlyWhereTheAlphaModeReadsIt) {
  TempDir dir;
  writeFile(dir / "albedo.png", zeroPng(4, 2));
  nlohmann::json j = quadWithNormalMap();
  writeFile(dir / "normal.png", zeroPng(2, 2));
  for (const char* mode : {"OPAQUE", "MASK", "BLEND"}) {
    SCOPED_TRACE(mode);
    j["materials"][0]["alphaMode"] = mode;
    auto s = scene::loadGltf(writeFile(dir / "scene.gltf", j.dump()));
    ASSERT_TRUE(s) << s.status().toString();
    const int channels = std::string(mode) == "OPAQUE" ? 3 : 4;
    EXPECT_EQ(s->textures[0].channels, channels);
    EXPECT_EQ(s->textures[0].rgba8.size(), 4u * 2 * static_cast<std::size_t>(channels));
    EXPECT_EQ(s->stats.image_bytes, 4u * 2 * static_cast<std::size_t>(channels));
  }
}

TEST(LightingImages, TheRuleFollowsWhatLightingReads) {
  nlohmann::json j = quadWithNormalMap();
  j["materials"][0]["emissiveTexture"] = {{"index", 2}};
  j["textures"].push_back({{"source", 2}});
  // No emissiveFactor (glTF default 0): the emissive texture changes nothing.
  scene::LightingImages l = scene::lightingImages(j);
  EXPECT_EQ(l.images, (std::vector<bool>{true, false, false}));
  j["materials"][0]["emissiveFactor"] = {1, 1, 1};
  l = scene::lightingImages(j);
  EXPECT_EQ(l.images, (std::vector<bool>{true, false, true}));
  // ... unless KHR_materials_emissive_strength turns it off.
  j["materials"][0]["extensions"]["KHR_materials_emissive_strength"]["emissiveStrength"] = 0;
  EXPECT_EQ(scene::lightingImages(j).images, (std::vector<bool>{true, false, false}));
  // A material no primitive uses decodes nothing.
  j["meshes"][0]["primitives"][0].erase("material");
  EXPECT_EQ(scene::lightingImages(j).images, (std::vector<bool>{false, false, false}));
  // Malformed entries are skipped, not trusted.
  EXPECT_TRUE(scene::lightingImages(nlohmann::json::parse(R"({"images": 3, "materials": [7]})")).images.empty());
}

}  // namespace
}  // namespace lightlink::testing
