// Materials: factors, KHR_materials_emissive_strength, texture references and their
// TEXCOORD sets, image decoding, and albedoAt / emissionAt at barycentric points.
#include <gtest/gtest.h>

#include "core/scene/load.h"
#include "core/scene/material_eval.h"
#include "tests/common/testing.h"
#include "tests/scene/gltf_builder.h"

namespace lightlink::scene {
namespace {

using testing::GltfBuilder;
using testing::TempDir;

constexpr float kLin128 = 0.2158605f;  // sRGB 128 -> linear
constexpr float kLin64 = 0.0512695f;

void expectNear(glm::vec3 actual, glm::vec3 expected, float tol = 2e-6f) {
  EXPECT_NEAR(actual.x, expected.x, tol) << "r";
  EXPECT_NEAR(actual.y, expected.y, tol) << "g";
  EXPECT_NEAR(actual.z, expected.z, tol) << "b";
}

// One quad (two triangles) with TEXCOORD_0 = the quad's corners and TEXCOORD_1 = the
// constant point (0.75, 0.25), a 2x2 BMP image, and materials built by the test.
struct TexturedQuad {
  GltfBuilder b;
  TexturedQuad() {
    // Texel (0,0) grey 128, texel (1,0) red 255, texel (0,1) grey 64, texel (1,1) white.
    const std::vector<std::uint8_t> rgb = {128, 128, 128, 255, 0, 0, 64, 64, 64, 255, 255, 255};
    const std::vector<std::uint8_t> img = testing::bmp24(2, 2, rgb);
    b.json()["images"] = {{{"uri", "data:image/bmp;base64," + testing::base64(img.data(), img.size())}}};
    b.json()["samplers"] = {{{"magFilter", 9728}, {"wrapS", 33071}, {"wrapT", 33071}}};
    b.json()["textures"] = {{{"source", 0}, {"sampler", 0}, {"name", "Checker"}}};
    const int pos = b.addVec3({{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}});
    const int uv0 = b.addVec2({{0, 0}, {1, 0}, {1, 1}, {0, 1}});
    const int uv1 = b.addVec2({{0.75f, 0.25f}, {0.75f, 0.25f}, {0.75f, 0.25f}, {0.75f, 0.25f}});
    const int idx = b.addIndicesU16({0, 1, 2, 0, 2, 3});
    b.json()["meshes"].push_back(
        {{"name", "Quad"},
         {"primitives", {{{"attributes", {{"POSITION", pos}, {"TEXCOORD_0", uv0}, {"TEXCOORD_1", uv1}}},
                          {"indices", idx},
                          {"material", 0}}}}});
    b.addNode({{"mesh", 0}});
  }
};

TEST(Materials, FactorsStrengthAndFlagsAreRead) {
  TempDir dir;
  TexturedQuad q;
  q.b.json()["extensionsUsed"] = {"KHR_materials_emissive_strength"};
  q.b.json()["materials"] = {{{"name", "Lamp"},
                              {"pbrMetallicRoughness",
                               {{"baseColorFactor", {0.5, 0.25, 1.0, 0.75}}, {"metallicFactor", 0.1}, {"roughnessFactor", 0.7}}},
                              {"emissiveFactor", {1.0, 0.5, 0.0}},
                              {"extensions", {{"KHR_materials_emissive_strength", {{"emissiveStrength", 8}}}}},
                              {"doubleSided", true}}};
  Expected<Scene> scene = loadGltf(q.b.writeGltf(dir / "t.gltf"));
  ASSERT_TRUE(scene.hasValue()) << scene.status().toString();
  ASSERT_EQ(scene->materials.size(), 1u);
  const Material& m = scene->materials[0];
  EXPECT_EQ(m.name, "Lamp");
  EXPECT_EQ(m.base_color_factor, glm::vec4(0.5f, 0.25f, 1.0f, 0.75f));
  EXPECT_FLOAT_EQ(m.metallic, 0.1f);
  EXPECT_FLOAT_EQ(m.roughness, 0.7f);
  EXPECT_EQ(m.emissive_factor, glm::vec3(1.0f, 0.5f, 0.0f));
  EXPECT_FLOAT_EQ(m.emissive_strength, 8.0f);
  EXPECT_TRUE(m.double_sided);
  EXPECT_TRUE(m.isEmissive());
  EXPECT_FALSE(m.base_color_texture.valid());
  const MeshInstance& mesh = scene->meshes[0];
  expectNear(albedoAt(*scene, mesh, 0, {0.3f, 0.3f}), {0.5f, 0.25f, 1.0f});
  expectNear(emissionAt(*scene, mesh, 1, {0.1f, 0.2f}), {8.0f, 4.0f, 0.0f});
  EXPECT_NEAR(scene->emissiveArea(), 1.0, 1e-9);
}

TEST(Materials, TexturesDecodeAndSampleAtTheirTexcoordSet) {
  TempDir dir;
  TexturedQuad q;
  q.b.json()["materials"] = {{{"pbrMetallicRoughness",
                               {{"baseColorFactor", {0.5, 1.0, 1.0, 1.0}}, {"baseColorTexture", {{"index", 0}}}}},
                              {"emissiveFactor", {2.0, 2.0, 2.0}},
                              {"emissiveTexture", {{"index", 0}, {"texCoord", 1}}}}};
  Expected<Scene> scene = loadGltf(q.b.writeGltf(dir / "t.gltf"));
  ASSERT_TRUE(scene.hasValue()) << scene.status().toString();
  ASSERT_EQ(scene->textures.size(), 1u);
  const Texture& t = scene->textures[0];
  EXPECT_EQ(t.name, "Checker");
  ASSERT_EQ(t.width, 2);
  ASSERT_EQ(t.height, 2);
  // Opaque: RGB, the alpha nothing reads is not kept.
  EXPECT_EQ(t.channels, 3);
  EXPECT_EQ(t.rgba8, (std::vector<std::uint8_t>{128, 128, 128, 255, 0, 0, 64, 64, 64, 255, 255, 255}));
  EXPECT_TRUE(t.nearest);
  EXPECT_EQ(t.wrap_s, 33071);
  const Material& m = scene->materials[0];
  EXPECT_EQ(m.base_color_texture.texture, 0);
  EXPECT_EQ(m.base_color_texture.texcoord, 0);
  EXPECT_EQ(m.emissive_texture.texcoord, 1);
  const MeshInstance& mesh = scene->meshes[0];
  // Triangle 0 = (0,1,2): barycentric (u, v) weights corners 1 and 2. uv0 at (0.1,0.1)+...:
  // u = 0.2, v = 0.05 -> point (0.25, 0.05): texel (0, 0), grey 128, times factor (0.5, 1, 1).
  const glm::vec2 uv = texcoordAt(mesh, 0, 0, {0.2f, 0.05f});
  EXPECT_NEAR(uv.x, 0.25f, 1e-6f);
  EXPECT_NEAR(uv.y, 0.05f, 1e-6f);
  expectNear(albedoAt(*scene, mesh, 0, {0.2f, 0.05f}), {0.5f * kLin128, kLin128, kLin128});
  // Near corner 2 (1, 1): texel (1, 1), white.
  expectNear(albedoAt(*scene, mesh, 0, {0.0f, 0.9f}), {0.5f, 1.0f, 1.0f});
  // Triangle 1 = (0,2,3), near corner 3 (0, 1): texel (0, 1), grey 64.
  expectNear(albedoAt(*scene, mesh, 1, {0.0f, 0.9f}), {0.5f * kLin64, kLin64, kLin64});
  // Emission reads TEXCOORD_1 = (0.75, 0.25) everywhere: texel (1, 0), red.
  expectNear(emissionAt(*scene, mesh, 1, {0.0f, 0.9f}), {2.0f, 0.0f, 0.0f});
}

TEST(Materials, GlbImageInBufferViewDecodes) {
  TempDir dir;
  TexturedQuad q;
  const std::vector<std::uint8_t> img = testing::bmp24(2, 2, std::vector<std::uint8_t>(12, 64));
  const int view = q.b.addBufferView(img.data(), img.size());
  q.b.json()["images"] = {{{"bufferView", view}, {"mimeType", "image/bmp"}}};
  q.b.json()["materials"] = {{{"pbrMetallicRoughness", {{"baseColorTexture", {{"index", 0}}}}}}};
  Expected<Scene> scene = loadGltf(q.b.writeGlb(dir / "t.glb"));
  ASSERT_TRUE(scene.hasValue()) << scene.status().toString();
  expectNear(albedoAt(*scene, scene->meshes[0], 0, {0.2f, 0.2f}), glm::vec3(kLin64));
}

TEST(Materials, ImageBufferViewOutsideBufferIsInvalid) {
  TempDir dir;
  TexturedQuad q;
  const std::vector<std::uint8_t> img = testing::bmp24(2, 2, std::vector<std::uint8_t>(12, 64));
  const int view = q.b.addBufferView(img.data(), img.size());
  q.b.json()["bufferViews"][static_cast<std::size_t>(view)]["byteLength"] = 1 << 20;
  q.b.json()["images"] = {{{"bufferView", view}, {"mimeType", "image/bmp"}, {"name", "Atlas"}}};
  const std::string path = q.b.writeGlb(dir / "t.glb");
  Expected<Scene> scene = loadGltf(path);
  ASSERT_FALSE(scene.hasValue());
  EXPECT_EQ(scene.status().code(), Code::kInvalidInput);
  EXPECT_NE(scene.status().message().find(path), std::string::npos) << scene.status().message();
  EXPECT_NE(scene.status().message().find("image 0 'Atlas'"), std::string::npos) << scene.status().message();
  EXPECT_NE(scene.status().message().find("exceeds buffer 0"), std::string::npos) << scene.status().message();
}

TEST(Materials, UndecodableImageWarnsAndSamplesWhite) {
  TempDir dir;
  TexturedQuad q;
  q.b.json()["images"][0]["uri"] = "data:image/png;base64,AAAAAAAA";
  q.b.json()["materials"] = {{{"pbrMetallicRoughness", {{"baseColorTexture", {{"index", 0}}}}}}};
  Expected<Scene> scene = loadGltf(q.b.writeGltf(dir / "t.gltf"));
  ASSERT_TRUE(scene.hasValue()) << scene.status().toString();
  bool named = false;
  for (const std::string& w : scene->warnings) named = named || w.find("image 0") != std::string::npos;
  EXPECT_TRUE(named) << "no warning names image 0";
  expectNear(albedoAt(*scene, scene->meshes[0], 0, {0.2f, 0.2f}), glm::vec3(1.0f));
}

TEST(Materials, TextureOnMissingTexcoordSetFallsBackToFactor) {
  TempDir dir;
  GltfBuilder b;
  b.json()["images"] = TexturedQuad().b.json()["images"];
  b.json()["textures"] = {{{"source", 0}}};
  b.json()["materials"] = {{{"pbrMetallicRoughness",
                             {{"baseColorFactor", {0.25, 0.5, 0.75, 1}}, {"baseColorTexture", {{"index", 0}, {"texCoord", 1}}}}}}};
  b.addNode({{"mesh", b.addTriangles(testing::unitTriangle(), {0, 1, 2})}});
  b.json()["meshes"][0]["primitives"][0]["material"] = 0;
  Expected<Scene> scene = loadGltf(b.writeGltf(dir / "t.gltf"));
  ASSERT_TRUE(scene.hasValue()) << scene.status().toString();
  expectNear(albedoAt(*scene, scene->meshes[0], 0, {0.2f, 0.2f}), {0.25f, 0.5f, 0.75f});
  ASSERT_EQ(scene->warnings.size(), 1u);
  EXPECT_NE(scene->warnings[0].find("mesh 0 primitive 0"), std::string::npos) << scene->warnings[0];
  EXPECT_NE(scene->warnings[0].find("TEXCOORD_1"), std::string::npos) << scene->warnings[0];
}

TEST(Materials, TextureIndexOutOfRangeIsInvalid) {
  TempDir dir;
  TexturedQuad q;
  q.b.json()["materials"] = {{{"name", "Bad"}, {"emissiveTexture", {{"index", 4}}}}};
  const std::string path = q.b.writeGltf(dir / "t.gltf");
  Expected<Scene> scene = loadGltf(path);
  ASSERT_FALSE(scene.hasValue());
  EXPECT_EQ(scene.status().code(), Code::kInvalidInput);
  EXPECT_NE(scene.status().message().find("material 0 'Bad'"), std::string::npos) << scene.status().message();
  EXPECT_NE(scene.status().message().find("texture 4"), std::string::npos) << scene.status().message();
}

}  // namespace
}  // namespace lightlink::scene
