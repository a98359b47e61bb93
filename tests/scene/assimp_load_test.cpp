// OBJ (+MTL) and FBX ingest through assimp (core/scene/assimp_load.h) and the one entry
// point loadScene: materials reach the Scene, bad data names the file, object and field,
// files stay inside the scene's folder, and the shared game levels load.
#include <cmath>
#include <fstream>
#include <sstream>
#include <limits>
#include <memory>

#include <assimp/Exporter.hpp>
#include <assimp/material.h>
#include <assimp/scene.h>
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "core/common/png.h"
#include "core/scene/load.h"
#include "tests/common/testing.h"

namespace lightlink::scene {
namespace {

using ::testing::HasSubstr;
using lightlink::testing::TempDir;
using lightlink::testing::writeFile;

// A unit quad in object "Floor" (two triangles) plus a triangle in object "Wall".
const char* kQuadObj = R"(mtllib scene.mtl
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
o Wall
v 0 1 0
usemtl glow
f 1 2 5
)";

const char* kQuadMtl = R"(newmtl red
Kd 0.5 0.25 0.125
d 0.75
map_Kd tex/red.png
newmtl glow
Kd 0 0 0
Ke 4 2 1
Tr 0.25
)";

void writeRedPng(const std::filesystem::path& path) {
  std::filesystem::create_directories(path.parent_path());
  const std::uint8_t rgb[] = {255, 0, 0, 255, 0, 0, 255, 0, 0, 255, 0, 0};
  ASSERT_TRUE(writePngRgb8(path.string(), 2, 2, rgb, "test").isOk());
}

std::string readText(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

const Material* materialNamed(const Scene& scene, const std::string& name) {
  for (const Material& m : scene.materials)
    if (m.name == name) return &m;
  return nullptr;
}

bool anyWarningHas(const Scene& scene, const std::string& a, const std::string& b) {
  for (const std::string& w : scene.warnings)
    if (w.find(a) != std::string::npos && w.find(b) != std::string::npos) return true;
  return false;
}

TEST(AssimpLoad, ObjMaterialsKdKeDAndMapKdReachTheScene) {
  TempDir dir;
  const std::string obj = writeFile(dir / "scene.obj", kQuadObj);
  writeFile(dir / "scene.mtl", kQuadMtl);
  writeRedPng(dir.path() / "tex" / "red.png");
  Expected<Scene> scene = loadScene(obj);
  ASSERT_TRUE(scene.hasValue()) << scene.status().toString();
  EXPECT_EQ(scene->triangleCount(), 3u);
  EXPECT_EQ(scene->stats.degenerate_dropped, 0u);

  const Material* red = materialNamed(*scene, "red");
  ASSERT_NE(red, nullptr);
  EXPECT_FLOAT_EQ(red->base_color_factor.x, 0.5f);
  EXPECT_FLOAT_EQ(red->base_color_factor.y, 0.25f);
  EXPECT_FLOAT_EQ(red->base_color_factor.z, 0.125f);
  EXPECT_FLOAT_EQ(red->base_color_factor.w, 0.75f);  // d
  ASSERT_TRUE(red->base_color_texture.valid());
  const Texture& tex = scene->textures[static_cast<std::size_t>(red->base_color_texture.texture)];
  EXPECT_EQ(tex.width, 2);
  EXPECT_EQ(tex.height, 2);
  EXPECT_NEAR(tex.sampleSrgb({0.5f, 0.5f}).x, 1.0f, 1e-6f);
  EXPECT_NEAR(tex.sampleSrgb({0.5f, 0.5f}).y, 0.0f, 1e-6f);

  const Material* glow = materialNamed(*scene, "glow");
  ASSERT_NE(glow, nullptr);
  // Ke (4, 2, 1): factor <= 1 and the rest as strength, radiance as stored.
  EXPECT_FLOAT_EQ(glow->emissive_strength, 4.0f);
  EXPECT_FLOAT_EQ(glow->emissive_factor.x * glow->emissive_strength, 4.0f);
  EXPECT_FLOAT_EQ(glow->emissive_factor.y * glow->emissive_strength, 2.0f);
  EXPECT_FLOAT_EQ(glow->emissive_factor.z * glow->emissive_strength, 1.0f);
  EXPECT_FLOAT_EQ(glow->base_color_factor.w, 0.75f);  // Tr 0.25
  EXPECT_TRUE(glow->isEmissive());

  for (const MeshInstance& m : scene->meshes) {
    EXPECT_TRUE(m.is_static);
    EXPECT_EQ(m.normals.size(), m.positions.size());
    const std::string& material = scene->materials[static_cast<std::size_t>(m.material)].name;
    if (material == "red") {
      EXPECT_EQ(m.uv0.size(), m.positions.size());
      EXPECT_FALSE(m.normals_generated);
      for (const glm::vec3& n : m.normals) EXPECT_NEAR(n.y, 1.0f, 1e-6f);
    } else {
      EXPECT_TRUE(m.normals_generated);  // "Wall" has no vn
    }
  }
}

TEST(AssimpLoad, ObjUvsFollowTheGltfConventionOfVZeroAtTheTop) {
  TempDir dir;
  const std::string obj = writeFile(dir / "scene.obj", kQuadObj);
  writeFile(dir / "scene.mtl", kQuadMtl);
  writeRedPng(dir.path() / "tex" / "red.png");
  Expected<Scene> scene = loadScene(obj);
  ASSERT_TRUE(scene.hasValue()) << scene.status().toString();
  for (const MeshInstance& m : scene->meshes) {
    for (std::size_t v = 0; v < m.uv0.size(); ++v) {
      // vt (u, v) at a corner: x = u, z = v in kQuadObj; glTF's v is 1 - OBJ's.
      EXPECT_NEAR(m.uv0[v].x, m.positions[v].x, 1e-6f);
      EXPECT_NEAR(m.uv0[v].y, 1.0f - m.positions[v].z, 1e-6f);
    }
  }
}

TEST(AssimpLoad, MissingMapKdIsAWarningNamingTheFileAndMaterial) {
  TempDir dir;
  const std::string obj = writeFile(dir / "scene.obj", kQuadObj);
  writeFile(dir / "scene.mtl", kQuadMtl);  // tex/red.png not written
  Expected<Scene> scene = loadScene(obj);
  ASSERT_TRUE(scene.hasValue()) << scene.status().toString();
  const Material* red = materialNamed(*scene, "red");
  ASSERT_NE(red, nullptr);
  EXPECT_FALSE(red->base_color_texture.valid());
  EXPECT_FLOAT_EQ(red->base_color_factor.x, 0.5f);
  EXPECT_TRUE(anyWarningHas(*scene, "material 'red'", "tex/red.png")) << ::testing::PrintToString(scene->warnings);
}

TEST(AssimpLoad, UndecodableMapKdIsAWarning) {
  TempDir dir;
  const std::string obj = writeFile(dir / "scene.obj", kQuadObj);
  writeFile(dir / "scene.mtl", kQuadMtl);
  std::filesystem::create_directories(dir.path() / "tex");
  writeFile(dir / "tex/red.png", "not a png at all");
  Expected<Scene> scene = loadScene(obj);
  ASSERT_TRUE(scene.hasValue()) << scene.status().toString();
  EXPECT_FALSE(materialNamed(*scene, "red")->base_color_texture.valid());
  EXPECT_TRUE(anyWarningHas(*scene, "material 'red'", "cannot be decoded"));
}

TEST(AssimpLoad, MissingMtllibIsAWarning) {
  TempDir dir;
  const std::string obj = writeFile(dir / "scene.obj", kQuadObj);
  Expected<Scene> scene = loadScene(obj);
  ASSERT_TRUE(scene.hasValue()) << scene.status().toString();
  EXPECT_TRUE(anyWarningHas(*scene, "scene.mtl", "not found"));
}

TEST(AssimpLoad, DegenerateFacesAreDroppedWithACount) {
  TempDir dir;
  const std::string obj = writeFile(dir / "flat.obj", R"(o Thin
v 0 0 0
v 1 0 0
v 0 1 0
v 2 0 0
f 1 2 3
f 1 2 4
f 1 1 3
)");
  Expected<Scene> scene = loadScene(obj);
  ASSERT_TRUE(scene.hasValue()) << scene.status().toString();
  EXPECT_EQ(scene->triangleCount(), 1u);
  EXPECT_EQ(scene->stats.degenerate_dropped, 2u);
  EXPECT_TRUE(anyWarningHas(*scene, "object 'Thin'", "2 degenerate triangles dropped"))
      << ::testing::PrintToString(scene->warnings);
}

struct BadObj {
  const char* name;
  const char* text;
  std::vector<const char*> expected;  // substrings of the message
};

TEST(AssimpLoad, BadObjDataIsAnErrorNamingTheFileObjectAndField) {
  const BadObj cases[] = {
      {"nan.obj", "o Crate\nv 0 0 0\nv 1 0 0\nv nan 1 0\nf 1 2 3\n",
       {"nan.obj", "object 'Crate'", "position", "not finite", "line 4"}},
      {"index.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\no Bad\nf 1 2 7\n",
       {"index.obj", "line 5", "object 'Bad'", "vertex 7", "has 3"}},
      {"zero.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\no Zero\nf 1 2 0\n", {"zero.obj", "object 'Zero'", "vertex 0"}},
      {"relative.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\ng Rel\nf -1 -2 -9\n", {"relative.obj", "group 'Rel'", "vertex -9"}},
      {"uv.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\no Tex\nf 1/1 2/2 3/1\n",
       {"uv.obj", "object 'Tex'", "texture coordinate 2"}},
      {"empty.obj", "", {"empty.obj", "empty"}},
      {"nofaces.obj", "o Lonely\nv 0 0 0\nv 1 0 0\n", {"nofaces.obj", "no triangles"}},
  };
  for (const BadObj& c : cases) {
    SCOPED_TRACE(c.name);
    TempDir dir;
    const std::string path = writeFile(dir / c.name, c.text);
    Expected<Scene> scene = loadScene(path);
    ASSERT_FALSE(scene.hasValue());
    for (const char* part : c.expected) EXPECT_THAT(scene.status().message(), HasSubstr(part));
  }
}

TEST(AssimpLoad, AnUnknownExtensionListsTheAcceptedOnes) {
  TempDir dir;
  const std::string path = writeFile(dir / "model.stl", "solid x\nendsolid x\n");
  Expected<Scene> scene = loadScene(path);
  ASSERT_FALSE(scene.hasValue());
  EXPECT_EQ(scene.status().code(), Code::kUnsupported);
  for (const char* part : {"model.stl", ".stl", ".gltf", ".glb", ".obj", ".fbx"})
    EXPECT_THAT(scene.status().message(), HasSubstr(part));
}

TEST(AssimpLoad, MaxTrianglesIsHonoured) {
  TempDir dir;
  const std::string obj = writeFile(dir / "scene.obj", kQuadObj);
  writeFile(dir / "scene.mtl", kQuadMtl);
  LoadOptions options;
  options.max_triangles = 2;
  Expected<Scene> scene = loadScene(obj, options);
  ASSERT_FALSE(scene.hasValue());
  EXPECT_EQ(scene.status().code(), Code::kResourceExhausted);
  EXPECT_THAT(scene.status().message(), HasSubstr("max_triangles"));
}

// assimp's triangulation is quadratic in a polygon's corners: one face of 40,000 corners
// (240 KB) takes 3 s, 300,000 some minutes. Refused before it runs, naming the object.
TEST(AssimpLoad, AHugePolygonIsRefusedBeforeTriangulation) {
  TempDir dir;
  std::string text = "v 0 0 0\nv 1 0 0\nv 0 1 0\no Fan\nf";
  for (int i = 0; i < 40000; ++i) text += i % 3 == 0 ? " 1" : i % 3 == 1 ? " 2" : " 3";
  const std::string obj = writeFile(dir / "fan.obj", text + "\n");
  Expected<Scene> scene = loadScene(obj);
  ASSERT_FALSE(scene.hasValue());
  EXPECT_EQ(scene.status().code(), Code::kResourceExhausted);
  for (const char* part : {"fan.obj", "object 'Fan'", "40000 corners", "split the large polygons"})
    EXPECT_THAT(scene.status().message(), HasSubstr(part));
}

TEST(AssimpLoad, MaxImagePixelsIsHonoured) {
  TempDir dir;
  const std::string obj = writeFile(dir / "scene.obj", kQuadObj);
  writeFile(dir / "scene.mtl", kQuadMtl);
  writeRedPng(dir.path() / "tex" / "red.png");
  LoadOptions options;
  options.max_image_pixels = 3;  // the texture has 4
  Expected<Scene> scene = loadScene(obj, options);
  ASSERT_FALSE(scene.hasValue());
  EXPECT_EQ(scene.status().code(), Code::kResourceExhausted);
  EXPECT_THAT(scene.status().message(), HasSubstr("max_image_pixels"));
  EXPECT_THAT(scene.status().message(), HasSubstr("tex/red.png"));
}

// Confinement: an mtllib or texture outside the scene's folder is refused unless allowed.
TEST(AssimpLoad, AnMtllibOutsideTheFolderIsRefusedUnlessAllowed) {
  TempDir dir;
  std::filesystem::create_directories(dir.path() / "level");
  writeFile(dir / "outside.mtl", "newmtl secret\nKd 0.1 0.2 0.3\n");
  const std::string obj = writeFile(dir / "level/scene.obj", "mtllib ../outside.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\n"
                                                               "usemtl secret\nf 1 2 3\n");
  Expected<Scene> refused = loadScene(obj);
  ASSERT_FALSE(refused.hasValue());
  EXPECT_THAT(refused.status().message(), HasSubstr("outside.mtl"));
  EXPECT_THAT(refused.status().message(), HasSubstr("escapes the scene's folder"));

  LoadOptions allowed;
  allowed.files.allow_outside_folder = true;
  Expected<Scene> scene = loadScene(obj, allowed);
  ASSERT_TRUE(scene.hasValue()) << scene.status().toString();
  const Material* secret = materialNamed(*scene, "secret");
  ASSERT_NE(secret, nullptr);
  EXPECT_FLOAT_EQ(secret->base_color_factor.z, 0.3f);
}

TEST(AssimpLoad, ATextureOutsideTheFolderIsRefusedUnlessAllowed) {
  TempDir dir;
  std::filesystem::create_directories(dir.path() / "level");
  writeRedPng(dir.path() / "red.png");
  const std::string obj = writeFile(dir / "level/scene.obj", "mtllib scene.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\n"
                                                               "usemtl red\nf 1 2 3\n");
  writeFile(dir / "level/scene.mtl", "newmtl red\nKd 1 1 1\nmap_Kd ../red.png\n");
  for (bool load_textures : {true, false}) {
    LoadOptions options;
    options.load_textures = load_textures;
    Expected<Scene> refused = loadScene(obj, options);
    ASSERT_FALSE(refused.hasValue()) << load_textures;
    EXPECT_THAT(refused.status().message(), HasSubstr("../red.png"));
    EXPECT_THAT(refused.status().message(), HasSubstr("material 'red'"));
  }
  LoadOptions allowed;
  allowed.files.allow_outside_folder = true;
  Expected<Scene> scene = loadScene(obj, allowed);
  ASSERT_TRUE(scene.hasValue()) << scene.status().toString();
  EXPECT_TRUE(materialNamed(*scene, "red")->base_color_texture.valid());
}

// A small FBX, written by assimp's own exporter from a hand-built aiScene: one quad on node
// "Crate", translated by (10, 0, 0), with a diffuse material.
std::unique_ptr<aiScene> crateScene(float first_x) {
  auto scene = std::make_unique<aiScene>();
  scene->mRootNode = new aiNode("Root");
  auto* crate = new aiNode("Crate");
  crate->mParent = scene->mRootNode;
  crate->mTransformation = aiMatrix4x4(1, 0, 0, 10, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1);
  crate->mNumMeshes = 1;
  crate->mMeshes = new unsigned[1]{0};
  scene->mRootNode->mNumChildren = 1;
  scene->mRootNode->mChildren = new aiNode*[1]{crate};

  auto* mesh = new aiMesh();
  mesh->mName = "CrateMesh";
  mesh->mPrimitiveTypes = aiPrimitiveType_TRIANGLE;
  mesh->mNumVertices = 4;
  mesh->mVertices = new aiVector3D[4]{{first_x, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}};
  mesh->mNumFaces = 2;
  mesh->mFaces = new aiFace[2];
  const unsigned corners[2][3] = {{0, 1, 2}, {0, 2, 3}};
  for (int f = 0; f < 2; ++f) {
    mesh->mFaces[f].mNumIndices = 3;
    mesh->mFaces[f].mIndices = new unsigned[3]{corners[f][0], corners[f][1], corners[f][2]};
  }
  mesh->mMaterialIndex = 0;
  scene->mNumMeshes = 1;
  scene->mMeshes = new aiMesh*[1]{mesh};

  auto* material = new aiMaterial();
  const aiString name("Paint");
  material->AddProperty(&name, AI_MATKEY_NAME);
  const aiColor3D diffuse(0.2f, 0.4f, 0.6f);
  material->AddProperty(&diffuse, 1, AI_MATKEY_COLOR_DIFFUSE);
  scene->mNumMaterials = 1;
  scene->mMaterials = new aiMaterial*[1]{material};
  return scene;
}

std::string exportFbx(const aiScene& scene, const std::filesystem::path& path) {
  Assimp::Exporter exporter;
  EXPECT_EQ(exporter.Export(&scene, "fbxa", path.string()), aiReturn_SUCCESS) << exporter.GetErrorString();
  return path.string();
}

TEST(AssimpLoad, FbxLoadsNodesTransformsAndMaterials) {
  TempDir dir;
  const std::string fbx = exportFbx(*crateScene(0.0f), dir / "crate.fbx");
  Expected<Scene> scene = loadScene(fbx);
  ASSERT_TRUE(scene.hasValue()) << scene.status().toString();
  EXPECT_EQ(scene->triangleCount(), 2u);
  ASSERT_EQ(scene->meshes.size(), 1u);
  EXPECT_THAT(scene->meshes[0].name, HasSubstr("Crate"));
  // assimp's exporter writes UnitScaleFactor 1 (a centimetre per unit): x 10..11 cm.
  EXPECT_NEAR(scene->bounds.min.x, 0.10f, 1e-6f);
  EXPECT_NEAR(scene->bounds.max.x, 0.11f, 1e-6f);
  const Material& m = scene->materialOf(scene->meshes[0]);
  EXPECT_EQ(m.name, "Paint");
  EXPECT_NEAR(m.base_color_factor.y, 0.4f, 1e-6f);
}

// UnitScaleFactor is centimetres per unit (Blender writes 100 for metres): lengths come out in metres.
TEST(AssimpLoad, FbxUnitsAreConvertedToMetres) {
  TempDir dir;
  const std::string fbx = exportFbx(*crateScene(0.0f), dir / "crate.fbx");
  std::string text = readText(fbx);
  const std::string cm = "\"UnitScaleFactor\", \"double\", \"Number\", \"\", 1\n";
  const std::size_t at = text.find(cm);
  ASSERT_NE(at, std::string::npos) << "assimp's ASCII FBX no longer states its unit this way";
  text.replace(at, cm.size(), "\"UnitScaleFactor\", \"double\", \"Number\", \"\", 100\n");
  const std::string metres = writeFile(dir / "metres.fbx", text);
  Expected<Scene> scene = loadScene(metres);
  ASSERT_TRUE(scene.hasValue()) << scene.status().toString();
  EXPECT_NEAR(scene->bounds.min.x, 10.0f, 1e-4f);
  EXPECT_NEAR(scene->bounds.max.x, 11.0f, 1e-4f);
  EXPECT_NEAR(scene->bounds.max.y, 1.0f, 1e-5f);
}

TEST(AssimpLoad, FbxWithANanPositionNamesTheNode) {
  TempDir dir;
  const std::string fbx = exportFbx(*crateScene(std::numeric_limits<float>::quiet_NaN()), dir / "bad.fbx");
  Expected<Scene> scene = loadScene(fbx);
  ASSERT_FALSE(scene.hasValue());
  EXPECT_THAT(scene.status().message(), HasSubstr("bad.fbx"));
  EXPECT_THAT(scene.status().message(), HasSubstr("node '"));
  EXPECT_THAT(scene.status().message(), HasSubstr("Crate"));
  EXPECT_THAT(scene.status().message(), HasSubstr("position"));
}

TEST(AssimpLoad, LoadSceneStillReadsGltf) {
  if (lightlink::testing::sharedScenesDir().empty()) GTEST_SKIP() << "../shared/scenes is not available";
  const auto gltf = lightlink::testing::sharedScenesDir() / "cornell_box_original_gltf/CornellBox-Original.gltf";
  Expected<Scene> scene = loadScene(gltf.string());
  ASSERT_TRUE(scene.hasValue()) << scene.status().toString();
  EXPECT_EQ(scene->stats.triangles_in, 32u);
}

// The five game levels and McGuire's Cornell box: OBJ + MTL whose textures are not shipped.
TEST(AssimpLoad, SharedObjLevelsLoadWithMissingTexturesAsWarnings) {
  if (lightlink::testing::sharedScenesDir().empty()) GTEST_SKIP() << "../shared/scenes is not available";
  struct Level {
    const char* file;
    std::size_t triangles;  // as stored (shared/scenes/README.md)
    std::size_t materials;  // README; assimp's unused DefaultMaterial is not counted
  };
  const Level levels[] = {
      {"cornell_box_mcguire_obj/CornellBox-Original.obj", 36, 8},
      {"redeclipse_cyanide_obj/cyanide.obj", 34876, 62},
      {"redeclipse_institute_obj/institute.obj", 35376, 122},
      {"tesseract_steelribs_obj/steelribs.obj", 45904, 38},
      {"sauerbraten_memento_obj/memento.obj", 50701, 102},
      {"sauerbraten_forge_obj/forge.obj", 59582, 44},
  };
  for (const Level& level : levels) {
    SCOPED_TRACE(level.file);
    LoadOptions options;
    options.load_textures = true;
    Expected<Scene> scene = loadScene((lightlink::testing::sharedScenesDir() / level.file).string(), options);
    ASSERT_TRUE(scene.hasValue()) << scene.status().toString();
    EXPECT_EQ(scene->stats.triangles_in, level.triangles);
    EXPECT_EQ(scene->materials.size(), level.materials);
    EXPECT_EQ(scene->triangleCount() + scene->stats.degenerate_dropped, level.triangles);
  }
}

}  // namespace
}  // namespace lightlink::scene
