// The glTF written back must give, when loaded again, exactly the geometry and uv1 the
// unwrap produced (bit for bit; the lightmap uv doubles as TEXCOORD_0 where there was none),
// keep existing TEXCOORD_1 bit-exactly, give instanced meshes their own uv1, be
// byte-identical across runs, and bind the lighting it is given only where it belongs.
#include <gtest/gtest.h>

#include <cstdlib>
#include <cstring>
#include <fstream>
#include <sstream>

#include <ImfRgbaFile.h>
#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "core/charts/gltf_lighting.h"
#include "core/charts/gltf_writer.h"
#include "core/charts/unwrap.h"
#include "core/charts/unwrap_command.h"
#include "core/scene/load.h"
#include "tests/charts/atlas_oracle.h"
#include "tests/common/testing.h"

namespace lightlink::charts {
namespace {

namespace fs = std::filesystem;

std::string readBytes(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

template <typename T>
bool sameBits(const std::vector<T>& a, const std::vector<T>& b) {
  return a.size() == b.size() && (a.empty() || std::memcmp(a.data(), b.data(), a.size() * sizeof(T)) == 0);
}

void expectSameGeometry(const scene::Scene& a, const scene::Scene& b) {
  ASSERT_EQ(a.meshes.size(), b.meshes.size());
  for (std::size_t m = 0; m < a.meshes.size(); ++m) {
    SCOPED_TRACE(a.meshes[m].name);
    EXPECT_TRUE(sameBits(a.meshes[m].positions, b.meshes[m].positions));
    // A mesh without uv0 comes back with the lightmap uv as TEXCOORD_0 (glTF's sets start at 0).
    EXPECT_TRUE(sameBits(a.meshes[m].uv0, b.meshes[m].uv0) ||
                (a.meshes[m].uv0.empty() && sameBits(b.meshes[m].uv0, b.meshes[m].uv1)));
    EXPECT_TRUE(sameBits(a.meshes[m].uv1, b.meshes[m].uv1));
    EXPECT_EQ(a.meshes[m].indices, b.meshes[m].indices);
  }
}

// The shared scene's path, or empty when it is not there (the test then skips, naming it).
fs::path scenePath(const char* folder, const char* file) {
  const fs::path dir = lightlink::testing::sharedScenesDir();
  return dir.empty() || !fs::exists(dir / folder / file) ? fs::path() : dir / folder / file;
}

std::string missingScene(const char* folder, const char* file) {
  return fmt::format("../shared/scenes/{}/{} not found: this test needs the shared scenes", folder, file);
}

class WriterRoundTrip : public ::testing::TestWithParam<std::pair<const char*, const char*>> {};

TEST_P(WriterRoundTrip, ReloadGivesTheUnwrappedSceneBitExactly) {
  const fs::path in = scenePath(GetParam().first, GetParam().second);
  if (in.empty()) GTEST_SKIP() << missingScene(GetParam().first, GetParam().second);
  Expected<scene::Scene> scene = scene::loadGltf(in.string(), {.load_textures = false});
  ASSERT_TRUE(scene) << scene.status().toString();
  Expected<UnwrapResult> result = unwrap(*scene, {});
  ASSERT_TRUE(result) << result.status().toString();
  lightlink::testing::TempDir tmp;
  for (const char* ext : {".gltf", ".glb"}) {
    const fs::path out = tmp / (std::string("out") + ext);
    ASSERT_TRUE(writeGltfWithLightmapUv(in.string(), *scene, result->atlas, out.string()));
    Expected<scene::Scene> again = scene::loadGltf(out.string(), {.load_textures = false});
    ASSERT_TRUE(again) << again.status().toString();
    expectSameGeometry(*scene, *again);
  }
}

INSTANTIATE_TEST_SUITE_P(
    SharedScenes, WriterRoundTrip,
    ::testing::Values(std::pair{"cornell_box_original_gltf", "CornellBox-Original.gltf"},
                      std::pair{"cornell_box_vinc3r_lightmapuv", "cornellBox-2.80-Eevee-gltf.gltf"},
                      std::pair{"khronos_LightsPunctualLamp", "LightsPunctualLamp.gltf"},
                      std::pair{"sauerbraten_zdm2_level_gltf", "zdm2.glb"}),
    [](const auto& info) { return std::string(info.param.first); });

TEST(GltfWriter, ExistingLightmapUvSurvivesBitExactly) {
  const fs::path in = scenePath("khronos_MultiUVTest", "MultiUVTest.gltf");
  if (in.empty()) GTEST_SKIP() << missingScene("khronos_MultiUVTest", "MultiUVTest.gltf");
  Expected<scene::Scene> original = scene::loadGltf(in.string(), {.load_textures = false});
  ASSERT_TRUE(original);
  scene::Scene scene = *original;
  UnwrapOptions keep;  // this TEXCOORD_1 maps a texture, not a lightmap: auto would regenerate
  keep.uv_mode = UvMode::kKeep;
  Expected<UnwrapResult> result = unwrap(scene, keep);
  ASSERT_TRUE(result);
  EXPECT_FALSE(result->report.generated);
  lightlink::testing::TempDir tmp;
  ASSERT_TRUE(writeGltfWithLightmapUv(in.string(), scene, result->atlas, (tmp / "out.gltf").string()));
  Expected<scene::Scene> again = scene::loadGltf((tmp / "out.gltf").string(), {.load_textures = false});
  ASSERT_TRUE(again);
  expectSameGeometry(*original, *again);
  // The textures were copied next to the output.
  EXPECT_TRUE(fs::exists(tmp / "uv1.png"));
}

TEST(GltfWriter, OutputIsDeterministicAndNeverOverwritesTheInput) {
  const fs::path in = scenePath("cornell_box_vinc3r_lightmapuv", "cornellBox-2.80-Eevee-gltf.gltf");
  if (in.empty()) GTEST_SKIP() << missingScene("cornell_box_vinc3r_lightmapuv", "cornellBox-2.80-Eevee-gltf.gltf");
  lightlink::testing::TempDir tmp;
  for (const char* name : {"a", "b"}) {
    UnwrapCommand cmd;
    cmd.input_path = in.string();
    cmd.output_path = (tmp / (std::string(name) + ".gltf")).string();
    cmd.preview_png = (tmp / (std::string(name) + ".png")).string();
    Expected<UnwrapReport> report = runUnwrap(cmd);
    ASSERT_TRUE(report) << report.status().toString();
  }
  EXPECT_EQ(readBytes(tmp / "a.bin"), readBytes(tmp / "b.bin"));
  EXPECT_EQ(readBytes(tmp / "a.png"), readBytes(tmp / "b.png"));
  std::string a = readBytes(tmp / "a.gltf"), b = readBytes(tmp / "b.gltf");
  // Only the buffer file name differs.
  const auto pos = b.find("\"b.bin\"");
  ASSERT_NE(pos, std::string::npos);
  b.replace(pos, 7, "\"a.bin\"");
  EXPECT_EQ(a, b);

  Expected<scene::Scene> scene = scene::loadGltf(in.string(), {.load_textures = false});
  ASSERT_TRUE(scene);
  Expected<UnwrapResult> result = unwrap(*scene, {});
  ASSERT_TRUE(result);
  const Status s = writeGltfWithLightmapUv(in.string(), *scene, result->atlas, in.string());
  EXPECT_EQ(s.code(), Code::kInvalidInput) << s.toString();
}

std::string base64(const std::string& bytes) {
  static const char* k = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  for (std::size_t i = 0; i < bytes.size(); i += 3) {
    std::uint32_t v = static_cast<std::uint8_t>(bytes[i]) << 16;
    if (i + 1 < bytes.size()) v |= static_cast<std::uint8_t>(bytes[i + 1]) << 8;
    if (i + 2 < bytes.size()) v |= static_cast<std::uint8_t>(bytes[i + 2]);
    out += k[(v >> 18) & 63];
    out += k[(v >> 12) & 63];
    out += i + 1 < bytes.size() ? k[(v >> 6) & 63] : '=';
    out += i + 2 < bytes.size() ? k[v & 63] : '=';
  }
  return out;
}

TEST(GltfWriter, InstancedMeshGetsOneCopyPerStaticNode) {
  // One quad mesh (2 triangles) placed by three nodes; the third is mirrored (scale -1)
  // and the second is dynamic.
  const float pos[12] = {0, 0, 0, 1, 0, 0, 1, 0, -1, 0, 0, -1};
  const std::uint16_t idx[6] = {0, 1, 2, 0, 2, 3};
  std::string bin(reinterpret_cast<const char*>(pos), sizeof(pos));
  bin.append(reinterpret_cast<const char*>(idx), sizeof(idx));
  const std::string json = R"({
    "asset": {"version": "2.0"},
    "scene": 0, "scenes": [{"nodes": [0, 1, 2]}],
    "nodes": [{"mesh": 0}, {"mesh": 0, "translation": [3, 0, 0], "extras": {"lightlink": {"static": false}}},
              {"mesh": 0, "translation": [6, 0, 0], "scale": [-1, 1, 1]}],
    "meshes": [{"name": "quad", "primitives": [{"attributes": {"POSITION": 0}, "indices": 1}]}],
    "accessors": [
      {"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3", "min": [0, 0, -1], "max": [1, 0, 0]},
      {"bufferView": 1, "componentType": 5123, "count": 6, "type": "SCALAR"}],
    "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 48}, {"buffer": 0, "byteOffset": 48, "byteLength": 12}],
    "buffers": [{"byteLength": 60, "uri": "data:application/octet-stream;base64,)" + base64(bin) + R"("}]
  })";
  lightlink::testing::TempDir tmp;
  const std::string in = lightlink::testing::writeFile(tmp / "quads.gltf", json);
  Expected<scene::Scene> scene = scene::loadGltf(in);
  ASSERT_TRUE(scene) << scene.status().toString();
  ASSERT_EQ(scene->meshes.size(), 3u);
  Expected<UnwrapResult> result = unwrap(*scene, {});
  ASSERT_TRUE(result) << result.status().toString();
  EXPECT_EQ(result->report.charts, 2);
  const std::string out = (tmp / "quads_lm.glb").string();
  ASSERT_TRUE(writeGltfWithLightmapUv(in, *scene, result->atlas, out));
  Expected<scene::Scene> again = scene::loadGltf(out);
  ASSERT_TRUE(again) << again.status().toString();
  expectSameGeometry(*scene, *again);
  // The dynamic node keeps the original mesh (no TEXCOORD_1); each static node has a copy.
  EXPECT_EQ(again->meshes[1].gltf_mesh, 0);
  EXPECT_TRUE(again->meshes[1].uv1.empty());
  EXPECT_NE(again->meshes[0].gltf_mesh, 0);
  EXPECT_NE(again->meshes[2].gltf_mesh, 0);
  EXPECT_NE(again->meshes[0].gltf_mesh, again->meshes[2].gltf_mesh);
  EXPECT_NE(again->meshes[0].uv1, again->meshes[2].uv1);
  const testing::OracleResult oracle = testing::checkWithOracle(*again, result->atlas);
  EXPECT_EQ(oracle.chart_overlap_texels + oracle.flipped + oracle.gutter_violations, 0u) << oracle.first_problem;
}

TEST(GltfWriter, ReplacedTexcoord1MovesWithItsMaterial) {
  // Quad A has TEXCOORD_1, sampled by its material's base colour; quad B has none, so the
  // mixed-scene policy regenerates both and A's old set must survive as TEXCOORD_2.
  const float pos[12] = {0, 0, 0, 1, 0, 0, 1, 0, -1, 0, 0, -1};
  const float uv[8] = {0, 0, 1, 0, 1, 1, 0, 1};
  const std::uint16_t idx[6] = {0, 1, 2, 0, 2, 3};
  std::string bin(reinterpret_cast<const char*>(pos), sizeof(pos));
  bin.append(reinterpret_cast<const char*>(uv), sizeof(uv));
  bin.append(reinterpret_cast<const char*>(idx), sizeof(idx));
  const std::string json = R"({
    "asset": {"version": "2.0"},
    "scene": 0, "scenes": [{"nodes": [0, 1]}],
    "nodes": [{"mesh": 0}, {"mesh": 1, "translation": [3, 0, 0]}],
    "meshes": [{"primitives": [{"attributes": {"POSITION": 0, "TEXCOORD_1": 1}, "indices": 2, "material": 0}]},
               {"primitives": [{"attributes": {"POSITION": 0}, "indices": 2, "material": 0}]}],
    "materials": [{"pbrMetallicRoughness": {"baseColorTexture": {"index": 0, "texCoord": 1}}}],
    "textures": [{"source": 0}], "images": [{"uri": "missing.png"}],
    "accessors": [
      {"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3", "min": [0, 0, -1], "max": [1, 0, 0]},
      {"bufferView": 1, "componentType": 5126, "count": 4, "type": "VEC2"},
      {"bufferView": 2, "componentType": 5123, "count": 6, "type": "SCALAR"}],
    "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 48}, {"buffer": 0, "byteOffset": 48, "byteLength": 32},
                    {"buffer": 0, "byteOffset": 80, "byteLength": 12}],
    "buffers": [{"byteLength": 92, "uri": "data:application/octet-stream;base64,)" + base64(bin) + R"("}]
  })";
  lightlink::testing::TempDir tmp;
  const std::string in = lightlink::testing::writeFile(tmp / "mixed.gltf", json);
  Expected<scene::Scene> scene = scene::loadGltf(in, {.load_textures = false});
  ASSERT_TRUE(scene) << scene.status().toString();
  Expected<UnwrapResult> result = unwrap(*scene, {});
  ASSERT_TRUE(result) << result.status().toString();
  ASSERT_TRUE(result->report.generated);
  const fs::path out = tmp / "out" / "mixed_lm.gltf";
  fs::create_directories(out.parent_path());
  ASSERT_TRUE(writeGltfWithLightmapUv(in, *scene, result->atlas, out.string()));
  const nlohmann::json j = nlohmann::json::parse(readBytes(out));
  const nlohmann::json& a = j["meshes"][0]["primitives"][0];
  const nlohmann::json& b = j["meshes"][1]["primitives"][0];
  ASSERT_TRUE(a["attributes"].contains("TEXCOORD_2")) << j["meshes"].dump();
  EXPECT_FALSE(b["attributes"].contains("TEXCOORD_2"));
  const int material_a = a["material"].get<int>();
  EXPECT_NE(material_a, 0);
  EXPECT_EQ(j["materials"][material_a]["pbrMetallicRoughness"]["baseColorTexture"]["texCoord"].get<int>(), 2);
  EXPECT_EQ(j["materials"][0]["pbrMetallicRoughness"]["baseColorTexture"]["texCoord"].get<int>(), 1);
  EXPECT_EQ(b["material"].get<int>(), 0);
  // The old set's values, re-gathered: reload and compare with the input's uv set.
  Expected<scene::Scene> again = scene::loadGltf(out.string(), {.load_textures = false});
  ASSERT_TRUE(again) << again.status().toString();
  expectSameGeometry(*scene, *again);
}

// A kept TEXCOORD_1 that came without a TEXCOORD_0 (invalid glTF: the sets start at 0) is
// written as set 0 too, so what lightlink writes validates even when its input did not.
TEST(GltfWriter, AKeptTexcoord1WithoutSet0BecomesSet0Too) {
  const float pos[12] = {0, 0, 0, 1, 0, 0, 1, 0, -1, 0, 0, -1};
  const float uv[8] = {0.1f, 0.1f, 0.9f, 0.1f, 0.9f, 0.9f, 0.1f, 0.9f};
  const std::uint16_t idx[6] = {0, 1, 2, 0, 2, 3};
  std::string bin(reinterpret_cast<const char*>(pos), sizeof(pos));
  bin.append(reinterpret_cast<const char*>(uv), sizeof(uv));
  bin.append(reinterpret_cast<const char*>(idx), sizeof(idx));
  const std::string json = R"({
    "asset": {"version": "2.0"},
    "scene": 0, "scenes": [{"nodes": [0]}],
    "nodes": [{"mesh": 0}],
    "meshes": [{"primitives": [{"attributes": {"POSITION": 0, "TEXCOORD_1": 1}, "indices": 2}]}],
    "accessors": [
      {"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3", "min": [0, 0, -1], "max": [1, 0, 0]},
      {"bufferView": 1, "componentType": 5126, "count": 4, "type": "VEC2"},
      {"bufferView": 2, "componentType": 5123, "count": 6, "type": "SCALAR"}],
    "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 48}, {"buffer": 0, "byteOffset": 48, "byteLength": 32},
                    {"buffer": 0, "byteOffset": 80, "byteLength": 12}],
    "buffers": [{"byteLength": 92, "uri": "data:application/octet-stream;base64,)" + base64(bin) + R"("}]
  })";
  lightlink::testing::TempDir tmp;
  const std::string in = lightlink::testing::writeFile(tmp / "kept.gltf", json);
  Expected<scene::Scene> scene = scene::loadGltf(in, {.load_textures = false});
  ASSERT_TRUE(scene) << scene.status().toString();
  Expected<UnwrapResult> result = unwrap(*scene, {});
  ASSERT_TRUE(result) << result.status().toString();
  ASSERT_FALSE(result->report.generated) << "the quad's own TEXCOORD_1 is kept";
  const fs::path out = tmp / "kept_lm.gltf";
  ASSERT_TRUE(writeGltfWithLightmapUv(in, *scene, result->atlas, out.string()));
  const nlohmann::json j = nlohmann::json::parse(readBytes(out));
  const nlohmann::json& attributes = j["meshes"][0]["primitives"][0]["attributes"];
  ASSERT_TRUE(attributes.contains("TEXCOORD_0")) << attributes.dump();
  EXPECT_EQ(attributes["TEXCOORD_0"], attributes["TEXCOORD_1"]);
}

// External images are copied next to the output only inside the output's folder: an image
// uri with `..` (readable when the scene is trusted with reading outside its folder) must not
// make the writer create files elsewhere.
TEST(GltfWriter, ImageCopiesStayInsideTheOutputFolder) {
  const float pos[9] = {0, 0, 0, 1, 0, 0, 0, 0, -1};
  const std::uint16_t idx[4] = {0, 1, 2, 0};
  std::string bin(reinterpret_cast<const char*>(pos), sizeof(pos));
  bin.append(reinterpret_cast<const char*>(idx), sizeof(idx));
  const std::string json = R"({
    "asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
    "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1, "material": 0}]}],
    "materials": [{"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}],
    "textures": [{"source": 0}], "images": [{"uri": "../img/evil.png"}],
    "accessors": [
      {"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3", "min": [0, 0, -1], "max": [1, 0, 0]},
      {"bufferView": 1, "componentType": 5123, "count": 3, "type": "SCALAR"}],
    "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 36}, {"buffer": 0, "byteOffset": 36, "byteLength": 6}],
    "buffers": [{"byteLength": 44, "uri": "data:application/octet-stream;base64,)" + base64(bin) + R"("}]
  })";
  lightlink::testing::TempDir tmp;
  fs::create_directories(tmp / "scene");
  fs::create_directories(tmp / "img");
  lightlink::testing::writeFile(tmp / "img" / "evil.png", "not really a png");
  const std::string in = lightlink::testing::writeFile(tmp / "scene" / "s.gltf", json);
  scene::LoadOptions trusted;
  trusted.load_textures = false;
  trusted.files.allow_outside_folder = true;
  Expected<scene::Scene> scene = scene::loadGltf(in, trusted);
  ASSERT_TRUE(scene) << scene.status().toString();
  Expected<UnwrapResult> result = unwrap(*scene, {});
  ASSERT_TRUE(result) << result.status().toString();
  const fs::path out = tmp / "a" / "b" / "s_lm.gltf";
  fs::create_directories(out.parent_path());
  // Confined (the default), the image outside the scene's folder is not read at all.
  const Status confined = writeGltfWithLightmapUv(in, *scene, result->atlas, out.string());
  EXPECT_FALSE(confined);
  EXPECT_NE(confined.message().find("escapes the scene's folder"), std::string::npos) << confined.message();
  // Trusted, it is read, but its copy would land in tmp/a/img: refused.
  const Status copied = writeGltfWithLightmapUv(in, *scene, result->atlas, out.string(), trusted.files);
  EXPECT_FALSE(copied);
  EXPECT_NE(copied.message().find("outside the output's folder"), std::string::npos) << copied.message();
  EXPECT_FALSE(fs::exists(tmp / "a" / "img" / "evil.png")) << "the writer created a file outside its output folder";
}


namespace lighting {

// A plain RGB half EXR, what bake writes as irradiance.exr: the validator opens the image
// the glTF names.
void writeRgbExr(const fs::path& path) {
  const int w = 4, h = 4;
  std::vector<Imf::Rgba> pixels(w * h, Imf::Rgba(1.0f, 0.5f, 0.25f, 1.0f));
  Imf::RgbaOutputFile file(path.string().c_str(), w, h, Imf::WRITE_RGB);
  file.setFrameBuffer(pixels.data(), 1, w);
  file.writePixels(h);
}

const nlohmann::json* mozLightmap(const nlohmann::json& gltf, const nlohmann::json& primitive) {
  if (!primitive.contains("material")) return nullptr;
  const nlohmann::json& m = gltf["materials"][primitive["material"].get<int>()];
  if (!m.contains("extensions") || !m["extensions"].contains("MOZ_lightmap")) return nullptr;
  return &m["extensions"]["MOZ_lightmap"];
}

// Every primitive with a TEXCOORD_1 (in these scenes: every static one) binds irradiance.exr
// through MOZ_lightmap on TEXCOORD_1, the others do not; returns how many are bound.
int expectBoundWhereLightmapped(const nlohmann::json& j) {
  int bound = 0;
  for (const nlohmann::json& mesh : j["meshes"])
    for (const nlohmann::json& prim : mesh["primitives"]) {
      const nlohmann::json* moz = mozLightmap(j, prim);
      const bool lightmapped = prim["attributes"].contains("TEXCOORD_1");
      EXPECT_EQ(moz != nullptr, lightmapped) << prim.dump();
      if (!moz) continue;
      ++bound;
      EXPECT_EQ((*moz)["texCoord"].get<int>(), 1);
      EXPECT_EQ((*moz)["intensity"].get<double>(), 1.0);
      const nlohmann::json& texture = j["textures"][(*moz)["index"].get<int>()];
      EXPECT_FALSE(texture.contains("source")) << "an EXR is not a core image: the extension names it";
      const int image = texture["extensions"]["LIGHTLINK_texture_exr"]["source"].get<int>();
      EXPECT_EQ(j["images"][image]["uri"], "irradiance.exr");
      EXPECT_FALSE(j["images"][image].contains("mimeType"));
      EXPECT_TRUE(prim["attributes"].contains("TEXCOORD_0"));
    }
  return bound;
}

bool uses(const nlohmann::json& j, const char* extension) {
  if (!j.contains("extensionsUsed")) return false;
  for (const nlohmann::json& e : j["extensionsUsed"])
    if (e == extension) return true;
  return false;
}

// Writes `in` (unwrapped) to `out_dir` with the irradiance map and a description, and
// without the map; checks both. The outputs stay in `out_dir` for the node validator test
// (tests/node/gltf_validator.mjs) when LIGHTLINK_GLTF_SAMPLES names it.
void writeBoundAndUnbound(const fs::path& in, const fs::path& out_dir, const std::string& stem) {
  Expected<scene::Scene> scene = scene::loadScene(in.string(), {.load_textures = false});
  ASSERT_TRUE(scene) << scene.status().toString();
  Expected<UnwrapResult> result = unwrap(*scene, {});
  ASSERT_TRUE(result) << result.status().toString();
  GltfLighting lighting;
  lighting.irradiance_uri = "irradiance.exr";
  lighting.description = {{"version", 1}, {"lightmap", {{"uri", "lightmap.exr"}, {"bands", 3}}}};
  const fs::path bound = out_dir / (stem + "_bound.gltf");
  ASSERT_TRUE(writeGltfWithLightmapUv(in.string(), *scene, result->atlas, bound.string(), {}, lighting));
  writeRgbExr(out_dir / "irradiance.exr");
  const nlohmann::json j = nlohmann::json::parse(readBytes(bound));
  EXPECT_GT(expectBoundWhereLightmapped(j), 0);
  EXPECT_TRUE(uses(j, "MOZ_lightmap") && uses(j, "LIGHTLINK_texture_exr") && uses(j, "LIGHTLINK_lighting"));
  EXPECT_EQ(j["extensions"]["LIGHTLINK_lighting"]["lightmap"]["bands"].get<int>(), 3);
  // The lightmapped scene loads again as before (the extensions are only pointers).
  Expected<scene::Scene> again = scene::loadGltf(bound.string(), {.load_textures = false});
  ASSERT_TRUE(again) << again.status().toString();
  expectSameGeometry(*scene, *again);
  for (const std::string& w : again->warnings)  // lightlink's own pointers load silently
    EXPECT_TRUE(w.find("MOZ_lightmap") == std::string::npos && w.find("LIGHTLINK_") == std::string::npos) << w;
  // Same inputs, same bytes.
  const fs::path twice = out_dir / (stem + "_bound_again.gltf");
  ASSERT_TRUE(writeGltfWithLightmapUv(in.string(), *scene, result->atlas, twice.string(), {}, lighting));
  std::string a = readBytes(bound), b = readBytes(twice);
  const std::string bin_a = "\"" + stem + "_bound.bin\"", bin_b = "\"" + stem + "_bound_again.bin\"";
  if (const auto pos = b.find(bin_b); pos != std::string::npos) b.replace(pos, bin_b.size(), bin_a);
  EXPECT_EQ(a, b);
  EXPECT_EQ(readBytes(out_dir / (stem + "_bound.bin")), readBytes(out_dir / (stem + "_bound_again.bin")));
  fs::remove(twice);
  fs::remove(out_dir / (stem + "_bound_again.bin"));

  lighting.irradiance_uri.clear();  // no irradiance map written: the description only
  const fs::path unbound = out_dir / (stem + "_unbound.gltf");
  ASSERT_TRUE(writeGltfWithLightmapUv(in.string(), *scene, result->atlas, unbound.string(), {}, lighting));
  const nlohmann::json u = nlohmann::json::parse(readBytes(unbound));
  EXPECT_FALSE(uses(u, "MOZ_lightmap") || uses(u, "LIGHTLINK_texture_exr"));
  EXPECT_TRUE(uses(u, "LIGHTLINK_lighting"));
  for (const nlohmann::json& mesh : u["meshes"])
    for (const nlohmann::json& prim : mesh["primitives"]) EXPECT_EQ(mozLightmap(u, prim), nullptr);
}

}  // namespace lighting

TEST(GltfLighting, BindsTheIrradianceMapOnlyWhenWritten) {
  const char* samples = std::getenv("LIGHTLINK_GLTF_SAMPLES");
  lightlink::testing::TempDir tmp;
  const fs::path dir = samples && *samples ? fs::path(samples) : tmp.path();
  fs::create_directories(dir);
  for (const auto& [folder, file, stem] :
       {std::tuple{"cornell_box_original_gltf", "CornellBox-Original.gltf", "cornell_gltf"},
        std::tuple{"cornell_box_mcguire_obj", "CornellBox-Sphere.obj", "cornell_obj"},
        std::tuple{"cornell_box_vinc3r_lightmapuv", "cornellBox-2.80-Eevee-gltf.gltf", "vinc3r"}}) {
    const fs::path in = scenePath(folder, file);
    if (in.empty()) GTEST_SKIP() << missingScene(folder, file);
    SCOPED_TRACE(folder);
    lighting::writeBoundAndUnbound(in, dir, stem);
  }
}

// Baking a lightmapped glTF again, into another folder: its irradiance texture is reused,
// not added twice, and the old irradiance.exr beside the input is never copied over the one
// the new bake wrote.
TEST(GltfLighting, ABakedGltfBakedAgainKeepsOneIrradianceTextureAndTheNewMap) {
  const fs::path in = scenePath("cornell_box_original_gltf", "CornellBox-Original.gltf");
  if (in.empty()) GTEST_SKIP() << missingScene("cornell_box_original_gltf", "CornellBox-Original.gltf");
  lightlink::testing::TempDir tmp;
  fs::create_directories(tmp / "first");
  fs::create_directories(tmp / "second");
  ASSERT_NO_FATAL_FAILURE(lighting::writeBoundAndUnbound(in, tmp / "first", "box"));
  lightlink::testing::writeFile(tmp / "second" / "irradiance.exr", "the second bake's map");
  const fs::path again_in = tmp / "first" / "box_bound.gltf";
  Expected<scene::Scene> scene = scene::loadGltf(again_in.string(), {.load_textures = false});
  ASSERT_TRUE(scene) << scene.status().toString();
  Expected<UnwrapResult> result = unwrap(*scene, {});
  ASSERT_TRUE(result) << result.status().toString();
  GltfLighting lighting;
  lighting.irradiance_uri = "irradiance.exr";
  const fs::path out = tmp / "second" / "box_lm.gltf";
  ASSERT_TRUE(writeGltfWithLightmapUv(again_in.string(), *scene, result->atlas, out.string(), {}, lighting));
  EXPECT_EQ(readBytes(tmp / "second" / "irradiance.exr"), "the second bake's map");
  const nlohmann::json j = nlohmann::json::parse(readBytes(out));
  EXPECT_EQ(j["textures"].size(), 1u) << j["textures"].dump();
  EXPECT_EQ(j["images"].size(), 1u) << j["images"].dump();
  EXPECT_GT(lighting::expectBoundWhereLightmapped(j), 0);
}

TEST(GltfLighting, AMaterialSharedWithADynamicNodeIsCopiedForTheLightmappedOnes) {
  // One quad mesh with material 0, placed by a static and a dynamic node.
  const float pos[12] = {0, 0, 0, 1, 0, 0, 1, 0, -1, 0, 0, -1};
  const std::uint16_t idx[6] = {0, 1, 2, 0, 2, 3};
  std::string bin(reinterpret_cast<const char*>(pos), sizeof(pos));
  bin.append(reinterpret_cast<const char*>(idx), sizeof(idx));
  const std::string json = R"({
    "asset": {"version": "2.0"},
    "scene": 0, "scenes": [{"nodes": [0, 1]}],
    "nodes": [{"mesh": 0}, {"mesh": 0, "translation": [3, 0, 0], "extras": {"lightlink": {"static": false}}}],
    "meshes": [{"name": "quad", "primitives": [{"attributes": {"POSITION": 0}, "indices": 1, "material": 0}]}],
    "materials": [{"name": "paint", "pbrMetallicRoughness": {"baseColorFactor": [0.5, 0.5, 0.5, 1]}}],
    "accessors": [
      {"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3", "min": [0, 0, -1], "max": [1, 0, 0]},
      {"bufferView": 1, "componentType": 5123, "count": 6, "type": "SCALAR"}],
    "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 48}, {"buffer": 0, "byteOffset": 48, "byteLength": 12}],
    "buffers": [{"byteLength": 60, "uri": "data:application/octet-stream;base64,)" + base64(bin) + R"("}]
  })";
  lightlink::testing::TempDir tmp;
  const std::string in = lightlink::testing::writeFile(tmp / "quads.gltf", json);
  Expected<scene::Scene> scene = scene::loadGltf(in);
  ASSERT_TRUE(scene) << scene.status().toString();
  Expected<UnwrapResult> result = unwrap(*scene, {});
  ASSERT_TRUE(result) << result.status().toString();
  GltfLighting lighting;
  lighting.irradiance_uri = "irradiance.exr";
  const fs::path out = tmp / "quads_lm.gltf";
  ASSERT_TRUE(writeGltfWithLightmapUv(in, *scene, result->atlas, out.string(), {}, lighting));
  const nlohmann::json j = nlohmann::json::parse(readBytes(out));
  EXPECT_EQ(lighting::expectBoundWhereLightmapped(j), 1);
  ASSERT_EQ(j["materials"].size(), 2u);
  EXPECT_FALSE(j["materials"][0].contains("extensions"));  // the dynamic node's, as it was
  EXPECT_EQ(j["materials"][1]["name"], "paint (lightmapped)");
  EXPECT_EQ(j["materials"][1]["pbrMetallicRoughness"]["baseColorFactor"], j["materials"][0]["pbrMetallicRoughness"]["baseColorFactor"]);
  // The bake writes irradiance.exr itself; an image of that name in the scene's folder is
  // never copied over it.
  EXPECT_FALSE(fs::exists(tmp / "irradiance.exr"));
}

}  // namespace
}  // namespace lightlink::charts
