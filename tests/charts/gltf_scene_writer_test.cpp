// The lightmapped scene written for an OBJ (or FBX) input is a fresh glTF built from the
// Scene (core/charts/gltf_scene_writer.h): loaded again with loadGltf it gives the same
// meshes in the same order, bit for bit, with TEXCOORD_1 intact, the materials' factors
// and emissive strength, and the base colour texture copied next to the output.
#include <gtest/gtest.h>

#include <cstring>
#include <filesystem>

#include "core/charts/gltf_writer.h"
#include "core/charts/unwrap_command.h"
#include "core/common/png.h"
#include "core/scene/load.h"
#include "tests/common/testing.h"

namespace lightlink::charts {
namespace {

namespace fs = std::filesystem;
using lightlink::testing::TempDir;
using lightlink::testing::writeFile;

template <typename T>
bool sameBits(const std::vector<T>& a, const std::vector<T>& b) {
  return a.size() == b.size() && (a.empty() || std::memcmp(a.data(), b.data(), a.size() * sizeof(T)) == 0);
}

// Two objects: a textured quad (material "red", Kd/d/map_Kd) and an emitter with Ke > 1.
std::string writeObjScene(const TempDir& dir) {
  fs::create_directories(dir.path() / "level" / "tex");
  writeFile(dir / "level/scene.mtl", "newmtl red\nKd 0.5 0.25 0.125\nd 0.75\nmap_Kd tex/red.png\n"
                                     "newmtl glow\nKd 0 0 0\nKe 4 2 1\n");
  const std::uint8_t rgb[] = {255, 0, 0, 255, 0, 0, 255, 0, 0, 255, 0, 0};
  EXPECT_TRUE(writePngRgb8((dir.path() / "level/tex/red.png").string(), 2, 2, rgb, "test").isOk());
  return writeFile(dir / "level/scene.obj", R"(mtllib scene.mtl
o Floor
v 0 0 0
v 1 0 0
v 1 0 1
v 0 0 1
vt 0 0
vt 1 0
vt 1 1
vt 0 1
vn 0 1 0
usemtl red
f 1/1/1 4/4/1 3/3/1 2/2/1
o Lamp
v 0 1 0
v 1 1 0
v 0 1 1
usemtl glow
f 5 7 6
)");
}

TEST(GltfSceneWriter, AnObjSceneRoundTripsThroughLoadGltfWithTexcoord1) {
  TempDir dir;
  const std::string obj = writeObjScene(dir);
  Expected<scene::Scene> scene = scene::loadScene(obj);
  ASSERT_TRUE(scene) << scene.status().toString();
  // A lightmap uv per vertex that no loader could invent: the writer must carry it as is.
  LightmapAtlas atlas;
  atlas.generated = true;
  atlas.meshes.resize(scene->meshes.size());
  for (scene::MeshInstance& m : scene->meshes) {
    m.uv1.clear();
    for (std::size_t v = 0; v < m.positions.size(); ++v)
      m.uv1.emplace_back(0.125f + 0.01f * static_cast<float>(v), 0.875f - 0.02f * static_cast<float>(v));
  }
  for (const char* ext : {".gltf", ".glb"}) {
    SCOPED_TRACE(ext);
    const fs::path out = dir / "out" / (std::string("scene_lm") + ext);
    fs::create_directories(out.parent_path());
    ASSERT_TRUE(writeGltfWithLightmapUv(obj, *scene, atlas, out.string()));
    Expected<scene::Scene> again = scene::loadGltf(out.string());
    ASSERT_TRUE(again) << again.status().toString();
    EXPECT_TRUE(again->warnings.empty()) << ::testing::PrintToString(again->warnings);
    ASSERT_EQ(again->meshes.size(), scene->meshes.size());
    for (std::size_t m = 0; m < scene->meshes.size(); ++m) {
      const scene::MeshInstance& a = scene->meshes[m];
      const scene::MeshInstance& b = again->meshes[m];
      SCOPED_TRACE(a.name);
      EXPECT_TRUE(sameBits(a.positions, b.positions));
      EXPECT_TRUE(sameBits(a.uv0, b.uv0) || (a.uv0.empty() && sameBits(b.uv0, b.uv1)));
      EXPECT_TRUE(sameBits(a.uv1, b.uv1));
      EXPECT_EQ(a.indices, b.indices);
      for (std::size_t v = 0; v < a.normals.size(); ++v) EXPECT_LT(glm::length(a.normals[v] - b.normals[v]), 1e-6f);
      const scene::Material& ma = scene->materialOf(a);
      const scene::Material& mb = again->materialOf(b);
      EXPECT_EQ(ma.name, mb.name);
      EXPECT_EQ(ma.base_color_factor, mb.base_color_factor);
      EXPECT_EQ(ma.emissive_factor * ma.emissive_strength, mb.emissive_factor * mb.emissive_strength);
      ASSERT_EQ(ma.base_color_texture.valid(), mb.base_color_texture.valid());
      if (mb.base_color_texture.valid()) {
        const scene::Texture& t = again->textures[static_cast<std::size_t>(mb.base_color_texture.texture)];
        EXPECT_EQ(t.width, 2);  // decoded from the copy next to the output
        EXPECT_NEAR(t.sampleSrgb({0.5f, 0.5f}).x, 1.0f, 1e-6f);
      }
    }
    EXPECT_TRUE(fs::exists(dir / "out/tex/red.png"));
  }
}

TEST(GltfSceneWriter, UnwrapOfAnObjWritesAGltfWhoseStaticMeshesAllHaveTexcoord1) {
  TempDir dir;
  UnwrapCommand command;
  command.input_path = writeObjScene(dir);
  command.output_path = (dir / "scene_lm.gltf").string();
  Expected<UnwrapReport> report = runUnwrap(command);
  ASSERT_TRUE(report) << report.status().toString();
  Expected<scene::Scene> again = scene::loadGltf(command.output_path);
  ASSERT_TRUE(again) << again.status().toString();
  ASSERT_EQ(again->meshes.size(), 2u);
  for (const scene::MeshInstance& m : again->meshes) EXPECT_TRUE(m.hasLightmapUv()) << m.name;
}

}  // namespace
}  // namespace lightlink::charts
