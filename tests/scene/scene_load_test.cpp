// Loading well-formed glTF: transforms, winding, normals, index and texcoord formats,
// .glb and external buffers, instancing, static flags, degenerate triangles.
#include <cmath>
#include <cstring>

#include <gtest/gtest.h>
#include <glm/gtc/matrix_transform.hpp>

#include "core/scene/load.h"
#include "tests/common/testing.h"
#include "tests/scene/gltf_builder.h"

namespace lightlink::scene {
namespace {

using testing::GltfBuilder;
using testing::TempDir;
using testing::unitTriangle;

Scene loadOk(const std::string& path) {
  Expected<Scene> scene = loadGltf(path);
  EXPECT_TRUE(scene.hasValue()) << scene.status().toString();
  if (!scene) return Scene{};
  return std::move(scene).value();
}

glm::vec3 geometricNormal(const MeshInstance& m, std::size_t triangle) {
  const glm::vec3 a = m.positions[m.indices[triangle * 3]];
  const glm::vec3 b = m.positions[m.indices[triangle * 3 + 1]];
  const glm::vec3 c = m.positions[m.indices[triangle * 3 + 2]];
  return glm::normalize(glm::cross(b - a, c - a));
}

void expectNear(glm::vec3 actual, glm::vec3 expected, float tol = 1e-5f) {
  EXPECT_NEAR(actual.x, expected.x, tol) << "x";
  EXPECT_NEAR(actual.y, expected.y, tol) << "y";
  EXPECT_NEAR(actual.z, expected.z, tol) << "z";
}

TEST(SceneLoad, IndexedTriangleWithBoundsAndStats) {
  TempDir dir;
  GltfBuilder b;
  const int mesh = b.addTriangles(unitTriangle(), {0, 1, 2}, "Tri");
  b.addNode({{"mesh", mesh}, {"name", "N"}});
  const Scene scene = loadOk(b.writeGltf(dir / "t.gltf"));
  ASSERT_EQ(scene.meshes.size(), 1u);
  const MeshInstance& m = scene.meshes[0];
  EXPECT_EQ(m.name, "Tri/0");
  EXPECT_EQ(m.gltf_node, 0);
  EXPECT_EQ(m.gltf_mesh, 0);
  EXPECT_EQ(m.gltf_primitive, 0);
  EXPECT_EQ(m.material, -1);
  EXPECT_TRUE(m.is_static);
  EXPECT_EQ(m.indices, (std::vector<std::uint32_t>{0, 1, 2}));
  EXPECT_TRUE(m.normals_generated);
  for (const glm::vec3& n : m.normals) expectNear(n, {0, 0, 1});
  EXPECT_EQ(scene.triangleCount(), 1u);
  EXPECT_EQ(scene.stats.triangles_in, 1u);
  EXPECT_EQ(scene.stats.vertices, 3u);
  EXPECT_EQ(scene.stats.degenerate_dropped, 0u);
  expectNear(scene.bounds.min, {0, 0, 0});
  expectNear(scene.bounds.max, {1, 1, 0});
  EXPECT_NEAR(scene.scale, std::sqrt(2.0f), 1e-6f);
  EXPECT_TRUE(scene.warnings.empty()) << scene.warnings.front();
  // The glTF default material: white, not emissive.
  EXPECT_EQ(scene.materialOf(m).base_color_factor, glm::vec4(1.0f));
  EXPECT_EQ(scene.emissiveArea(), 0.0);
}

TEST(SceneLoad, NonIndexedPrimitive) {
  TempDir dir;
  GltfBuilder b;
  std::vector<glm::vec3> p = unitTriangle();
  p.insert(p.end(), {{0, 0, 1}, {1, 0, 1}, {0, 1, 1}});
  const int mesh = b.addMesh({{"attributes", {{"POSITION", b.addVec3(p)}}}});
  b.addNode({{"mesh", mesh}});
  const Scene scene = loadOk(b.writeGltf(dir / "t.gltf"));
  ASSERT_EQ(scene.meshes.size(), 1u);
  EXPECT_EQ(scene.meshes[0].indices, (std::vector<std::uint32_t>{0, 1, 2, 3, 4, 5}));
  EXPECT_EQ(scene.meshes[0].name, "mesh0/0");
}

TEST(SceneLoad, IndexTypesU8U16U32) {
  TempDir dir;
  GltfBuilder b;
  const std::vector<glm::vec3> quad = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}};
  const int pos = b.addVec3(quad);
  const int i8 = b.addIndicesU8({0, 1, 2, 0, 2, 3});
  const int i16 = b.addIndicesU16({0, 1, 2, 0, 2, 3});
  const int i32 = b.addIndicesU32({0, 1, 2, 0, 2, 3});
  for (int idx : {i8, i16, i32}) {
    b.addNode({{"mesh", b.addMesh({{"attributes", {{"POSITION", pos}}}, {"indices", idx}})}});
  }
  const Scene scene = loadOk(b.writeGltf(dir / "t.gltf"));
  ASSERT_EQ(scene.meshes.size(), 3u);
  for (const MeshInstance& m : scene.meshes) {
    EXPECT_EQ(m.indices, (std::vector<std::uint32_t>{0, 1, 2, 0, 2, 3})) << m.name;
  }
}

TEST(SceneLoad, MatrixTransformIsColumnMajor) {
  TempDir dir;
  GltfBuilder b;
  const int mesh = b.addTriangles(unitTriangle(), {0, 1, 2});
  // Scale 2 then translate (10, 20, 30), column-major as glTF stores it.
  b.addNode({{"mesh", mesh},
             {"matrix", {2, 0, 0, 0, 0, 2, 0, 0, 0, 0, 2, 0, 10, 20, 30, 1}}});
  const Scene scene = loadOk(b.writeGltf(dir / "t.gltf"));
  ASSERT_EQ(scene.meshes.size(), 1u);
  expectNear(scene.meshes[0].positions[1], {12, 20, 30});
  expectNear(scene.meshes[0].positions[2], {10, 22, 30});
}

TEST(SceneLoad, TrsAppliesScaleThenRotationThenTranslation) {
  TempDir dir;
  GltfBuilder b;
  const int mesh = b.addTriangles(unitTriangle(), {0, 1, 2});
  const float s = std::sqrt(0.5f);
  // 90 degrees about +Z (x, y, z, w), scale x by 3.
  b.addNode({{"mesh", mesh},
             {"translation", {1, 2, 3}},
             {"rotation", {0, 0, s, s}},
             {"scale", {3, 1, 1}}});
  const Scene scene = loadOk(b.writeGltf(dir / "t.gltf"));
  ASSERT_EQ(scene.meshes.size(), 1u);
  // (1,0,0) -> scale (3,0,0) -> rotate (0,3,0) -> translate (1,5,3)
  expectNear(scene.meshes[0].positions[1], {1, 5, 3});
  // (0,1,0) -> (0,1,0) -> (-1,0,0) -> (0,2,3)
  expectNear(scene.meshes[0].positions[2], {0, 2, 3});
}

TEST(SceneLoad, NestedThreeLevelsComposeParentTimesChild) {
  TempDir dir;
  GltfBuilder b;
  const int mesh = b.addTriangles(unitTriangle(), {0, 1, 2});
  const float s = std::sqrt(0.5f);
  const int root = b.addNode({{"translation", {100, 0, 0}}});
  const int middle = b.addNode({{"rotation", {0, 0, s, s}}}, false);
  const int leaf = b.addNode({{"mesh", mesh}, {"scale", {2, 2, 2}}, {"translation", {1, 0, 0}}}, false);
  b.addChild(root, middle);
  b.addChild(middle, leaf);
  const Scene scene = loadOk(b.writeGltf(dir / "t.gltf"));
  ASSERT_EQ(scene.meshes.size(), 1u);
  // leaf: (1,0,0) -> (2,0,0) + (1,0,0) = (3,0,0); middle: rot90 -> (0,3,0); root: (100,3,0).
  expectNear(scene.meshes[0].positions[1], {100, 3, 0});
  expectNear(scene.meshes[0].positions[0], {100, 1, 0});
  const glm::mat4 expected = glm::translate(glm::mat4(1.0f), glm::vec3(100, 0, 0)) *
                             glm::rotate(glm::mat4(1.0f), glm::radians(90.0f), glm::vec3(0, 0, 1)) *
                             glm::translate(glm::mat4(1.0f), glm::vec3(1, 0, 0)) *
                             glm::scale(glm::mat4(1.0f), glm::vec3(2.0f));
  for (int c = 0; c < 4; ++c) {
    for (int r = 0; r < 4; ++r) {
      EXPECT_NEAR(scene.meshes[0].world_from_mesh[c][r], expected[c][r], 1e-5f) << c << "," << r;
    }
  }
}

TEST(SceneLoad, MirrorTransformKeepsFrontFacesFront) {
  TempDir dir;
  GltfBuilder b;
  const std::vector<glm::vec3> n = {{0, 0, 1}, {0, 0, 1}, {0, 0, 1}};
  const int mesh = b.addTriangles(unitTriangle(), {0, 1, 2}, "Tri", n);
  b.addNode({{"mesh", mesh}, {"scale", {1, 1, -1}}});  // mirror through z = 0
  b.addNode({{"mesh", mesh}, {"scale", {-1, 1, 1}}});  // mirror through x = 0
  const Scene scene = loadOk(b.writeGltf(dir / "t.gltf"));
  ASSERT_EQ(scene.meshes.size(), 2u);
  // Mirrored in z: the front (+Z) now faces -Z, and the stored normal agrees.
  expectNear(geometricNormal(scene.meshes[0], 0), {0, 0, -1});
  expectNear(scene.meshes[0].normals[0], {0, 0, -1});
  EXPECT_EQ(scene.meshes[0].indices, (std::vector<std::uint32_t>{0, 2, 1}));
  // Mirrored in x: the plane keeps facing +Z, so the winding must be flipped to stay front.
  expectNear(geometricNormal(scene.meshes[1], 0), {0, 0, 1});
  expectNear(scene.meshes[1].normals[0], {0, 0, 1});
}

TEST(SceneLoad, NormalsUseInverseTransposeAndAreRenormalised) {
  TempDir dir;
  GltfBuilder b;
  const float s = std::sqrt(0.5f);
  const std::vector<glm::vec3> n(3, glm::vec3(s, s, 0));
  const int mesh = b.addTriangles(unitTriangle(), {0, 1, 2}, "Tri", n);
  b.addNode({{"mesh", mesh}, {"scale", {2, 1, 1}}});
  const Scene scene = loadOk(b.writeGltf(dir / "t.gltf"));
  ASSERT_EQ(scene.meshes.size(), 1u);
  EXPECT_FALSE(scene.meshes[0].normals_generated);
  // inverse transpose of diag(2,1,1) = diag(0.5,1,1): (0.5, 1, 0) normalised.
  expectNear(scene.meshes[0].normals[0], glm::normalize(glm::vec3(0.5f, 1.0f, 0.0f)));
}

TEST(SceneLoad, GeneratedNormalsAreAreaWeighted) {
  TempDir dir;
  GltfBuilder b;
  // Vertex 0 is shared by a big triangle facing +Z (area 2) and a small one facing +X (area 0.5).
  const std::vector<glm::vec3> p = {{0, 0, 0}, {2, 0, 0}, {0, 2, 0}, {0, 1, 0}, {0, 0, 1}};
  const int mesh = b.addTriangles(p, {0, 1, 2, 0, 3, 4});
  b.addNode({{"mesh", mesh}});
  const Scene scene = loadOk(b.writeGltf(dir / "t.gltf"));
  ASSERT_EQ(scene.meshes.size(), 1u);
  const MeshInstance& m = scene.meshes[0];
  EXPECT_TRUE(m.normals_generated);
  EXPECT_EQ(scene.stats.normals_generated, 1u);
  expectNear(m.normals[0], glm::normalize(glm::vec3(0.5f, 0.0f, 2.0f)));
  expectNear(m.normals[1], {0, 0, 1});
  expectNear(m.normals[4], {1, 0, 0});
}

TEST(SceneLoad, StripsAndFansBecomeFrontFacingTriangles) {
  TempDir dir;
  GltfBuilder b;
  const std::vector<glm::vec3> strip = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {1, 1, 0}};
  const std::vector<glm::vec3> fan = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}};
  b.addNode({{"mesh", b.addMesh({{"attributes", {{"POSITION", b.addVec3(strip)}}}, {"mode", 5}})}});
  b.addNode({{"mesh", b.addMesh({{"attributes", {{"POSITION", b.addVec3(fan)}}}, {"mode", 6}})}});
  const Scene scene = loadOk(b.writeGltf(dir / "t.gltf"));
  ASSERT_EQ(scene.meshes.size(), 2u);
  EXPECT_EQ(scene.meshes[0].indices, (std::vector<std::uint32_t>{0, 1, 2, 1, 3, 2}));
  EXPECT_EQ(scene.meshes[1].indices, (std::vector<std::uint32_t>{1, 2, 0, 2, 3, 0}));
  for (const MeshInstance& m : scene.meshes) {
    for (std::size_t t = 0; t < m.triangleCount(); ++t) expectNear(geometricNormal(m, t), {0, 0, 1});
  }
}

TEST(SceneLoad, TexcoordsFloatBitExactAndNormalizedIntegers) {
  TempDir dir;
  GltfBuilder b;
  // Values that are not exactly representable in decimal text: must survive bit for bit.
  const std::vector<glm::vec2> uv0 = {{0.1f, 1.0f / 3.0f}, {-2.7f, 1e-30f}, {123.456f, 0.7f}};
  const std::vector<std::uint16_t> uv1_u16 = {0, 65535, 13107, 26214, 65535, 0};
  const int pos = b.addVec3(unitTriangle());
  const int t0 = b.addVec2(uv0);
  // Normalized u8 in a stride-4 view (2 bytes of data, 2 bytes of padding per element).
  const std::vector<std::uint8_t> strided = {0, 255, 9, 9, 51, 102, 9, 9, 255, 0, 9, 9};
  const int view = b.addBufferView(strided.data(), strided.size(), 4);
  b.json()["accessors"].push_back({{"bufferView", view}, {"componentType", 5121}, {"type", "VEC2"},
                                   {"count", 3}, {"normalized", true}});
  const int t8 = static_cast<int>(b.json()["accessors"].size() - 1);
  const int t16 = b.addAccessor(uv1_u16.data(), uv1_u16.size() * 2, 5123, "VEC2", 3, true);
  b.addNode({{"mesh", b.addMesh({{"attributes", {{"POSITION", pos}, {"TEXCOORD_0", t0}, {"TEXCOORD_1", t8}}}})}});
  b.addNode({{"mesh", b.addMesh({{"attributes", {{"POSITION", pos}, {"TEXCOORD_1", t16}}}})}});
  const Scene scene = loadOk(b.writeGltf(dir / "t.gltf"));
  ASSERT_EQ(scene.meshes.size(), 2u);
  const MeshInstance& a = scene.meshes[0];
  ASSERT_EQ(a.uv0.size(), 3u);
  EXPECT_EQ(std::memcmp(a.uv0.data(), uv0.data(), sizeof(glm::vec2) * 3), 0);
  ASSERT_TRUE(a.hasLightmapUv());
  EXPECT_EQ(a.uv1[0], glm::vec2(0.0f, 1.0f));
  EXPECT_FLOAT_EQ(a.uv1[1].x, 0.2f);
  EXPECT_FLOAT_EQ(a.uv1[1].y, 0.4f);
  EXPECT_EQ(a.uv1[2], glm::vec2(1.0f, 0.0f));
  const MeshInstance& c = scene.meshes[1];
  EXPECT_TRUE(c.uv0.empty());
  ASSERT_EQ(c.uv1.size(), 3u);
  EXPECT_FLOAT_EQ(c.uv1[1].x, 0.2f);
  EXPECT_FLOAT_EQ(c.uv1[1].y, 0.4f);
}

TEST(SceneLoad, InterleavedAttributesWithByteStride) {
  TempDir dir;
  GltfBuilder b;
  // position (12 B) + normal (12 B) + uv (8 B) per vertex: stride 32.
  struct Vertex {
    float p[3], n[3], uv[2];
  };
  const std::vector<Vertex> v = {{{0, 0, 0}, {0, 0, 1}, {0, 0}},
                                 {{1, 0, 0}, {0, 0, 1}, {1, 0}},
                                 {{0, 1, 0}, {0, 0, 1}, {0, 1}}};
  const int view = b.addBufferView(v.data(), v.size() * sizeof(Vertex), sizeof(Vertex));
  auto& acc = b.json()["accessors"];
  acc.push_back({{"bufferView", view}, {"byteOffset", 0}, {"componentType", 5126}, {"type", "VEC3"}, {"count", 3}});
  acc.push_back({{"bufferView", view}, {"byteOffset", 12}, {"componentType", 5126}, {"type", "VEC3"}, {"count", 3}});
  acc.push_back({{"bufferView", view}, {"byteOffset", 24}, {"componentType", 5126}, {"type", "VEC2"}, {"count", 3}});
  b.addNode({{"mesh", b.addMesh({{"attributes", {{"POSITION", 0}, {"NORMAL", 1}, {"TEXCOORD_0", 2}}}})}});
  const Scene scene = loadOk(b.writeGltf(dir / "t.gltf"));
  ASSERT_EQ(scene.meshes.size(), 1u);
  const MeshInstance& m = scene.meshes[0];
  expectNear(m.positions[1], {1, 0, 0});
  expectNear(m.normals[2], {0, 0, 1});
  EXPECT_FALSE(m.normals_generated);
  EXPECT_EQ(m.uv0[2], glm::vec2(0, 1));
}

TEST(SceneLoad, GlbAndExternalBinLoadLikeEmbedded) {
  TempDir dir;
  GltfBuilder b;
  const int mesh = b.addTriangles({{0, 0, 0}, {3, 0, 0}, {0, 3, 0}}, {0, 1, 2}, "Tri");
  b.addNode({{"mesh", mesh}});
  for (const std::string& path : {b.writeGlb(dir / "t.glb"), b.writeGltfWithBin(dir / "e.gltf", "e.bin"),
                                  b.writeGlb(dir / "renamed.bin.data")}) {
    const Scene scene = loadOk(path);
    ASSERT_EQ(scene.meshes.size(), 1u) << path;
    expectNear(scene.meshes[0].positions[1], {3, 0, 0});
    EXPECT_EQ(scene.source_path, path);
  }
}

TEST(SceneLoad, InstancingExpandsOneMeshPerNode) {
  TempDir dir;
  GltfBuilder b;
  const int mesh = b.addTriangles(unitTriangle(), {0, 1, 2});
  b.addNode({{"mesh", mesh}, {"translation", {0, 0, 0}}});
  b.addNode({{"mesh", mesh}, {"translation", {5, 0, 0}}});
  const Scene scene = loadOk(b.writeGltf(dir / "t.gltf"));
  ASSERT_EQ(scene.meshes.size(), 2u);
  EXPECT_EQ(scene.meshes[0].gltf_mesh, scene.meshes[1].gltf_mesh);
  expectNear(scene.meshes[1].positions[0], {5, 0, 0});
  EXPECT_EQ(scene.triangleCount(), 2u);
}

TEST(SceneLoad, WithoutScenesEveryRootNodeIsLoaded) {
  TempDir dir;
  GltfBuilder b;
  const int mesh = b.addTriangles(unitTriangle(), {0, 1, 2});
  const int parent = b.addNode({{"mesh", mesh}});
  const int child = b.addNode({{"mesh", mesh}, {"translation", {0, 0, 1}}}, false);
  b.addChild(parent, child);
  b.addNode({{"mesh", mesh}, {"translation", {0, 0, 2}}});
  b.json().erase("scenes");
  b.json().erase("scene");
  const Scene scene = loadOk(b.writeGltf(dir / "t.gltf"));
  EXPECT_EQ(scene.meshes.size(), 3u);
}

TEST(SceneLoad, OnlyTheDefaultSceneIsLoaded) {
  TempDir dir;
  GltfBuilder b;
  const int mesh = b.addTriangles(unitTriangle(), {0, 1, 2});
  b.addNode({{"mesh", mesh}});
  b.addNode({{"mesh", mesh}, {"translation", {0, 0, 1}}}, false);
  b.json()["scenes"].push_back({{"nodes", {1}}});
  b.json()["scene"] = 1;
  const Scene scene = loadOk(b.writeGltf(dir / "t.gltf"));
  ASSERT_EQ(scene.meshes.size(), 1u);
  EXPECT_EQ(scene.meshes[0].gltf_node, 1);
}

TEST(SceneLoad, StaticFlagIsInheritedUnlessOverridden) {
  TempDir dir;
  GltfBuilder b;
  const int mesh = b.addTriangles(unitTriangle(), {0, 1, 2});
  const nlohmann::json dynamic = {{"lightlink", {{"static", false}}}};
  const nlohmann::json fixed = {{"lightlink", {{"static", true}}}};
  const int root = b.addNode({{"mesh", mesh}, {"extras", dynamic}});
  const int child = b.addNode({{"mesh", mesh}}, false);
  const int grandchild = b.addNode({{"mesh", mesh}, {"extras", fixed}}, false);
  const int other = b.addNode({{"mesh", mesh}, {"extras", {{"unrelated", 1}}}});
  b.addChild(root, child);
  b.addChild(child, grandchild);
  const Scene scene = loadOk(b.writeGltf(dir / "t.gltf"));
  ASSERT_EQ(scene.meshes.size(), 4u);
  for (const MeshInstance& m : scene.meshes) {
    const bool expected = m.gltf_node == grandchild || m.gltf_node == other;
    EXPECT_EQ(m.is_static, expected) << "node " << m.gltf_node;
  }
  EXPECT_EQ(scene.staticTriangleCount(), 2u);
  EXPECT_EQ(scene.triangleCount(), 4u);
}

TEST(SceneLoad, LightmapScaleAndProbeLitFlagsAreInheritedUnlessOverridden) {
  TempDir dir;
  GltfBuilder b;
  const int mesh = b.addTriangles(unitTriangle(), {0, 1, 2});
  const int root = b.addNode({{"mesh", mesh}, {"extras", {{"lightlink", {{"lightmap_scale", 4.0}}}}}});
  const int child = b.addNode({{"mesh", mesh}}, false);
  const int grandchild = b.addNode({{"mesh", mesh}, {"extras", {{"lightlink", {{"lightmap", false}}}}}}, false);
  const int other = b.addNode({{"mesh", mesh}});
  b.addChild(root, child);
  b.addChild(child, grandchild);
  const Scene scene = loadOk(b.writeGltf(dir / "t.gltf"));
  ASSERT_EQ(scene.meshes.size(), 4u);
  for (const MeshInstance& m : scene.meshes) {
    EXPECT_EQ(m.lightmap_scale, m.gltf_node == other ? 1.0f : 4.0f) << "node " << m.gltf_node;
    EXPECT_EQ(m.probe_lit, m.gltf_node == grandchild) << "node " << m.gltf_node;
  }
  // Bad values are errors naming the node and the key.
  for (const nlohmann::json& bad : {nlohmann::json{{"lightmap_scale", 0.0}}, nlohmann::json{{"lightmap_scale", "2"}},
                                    nlohmann::json{{"lightmap_scale", 100.0}}, nlohmann::json{{"lightmap", 0}}}) {
    GltfBuilder c;
    const int m = c.addTriangles(unitTriangle(), {0, 1, 2});
    c.addNode({{"mesh", m}, {"name", "Statue"}, {"extras", {{"lightlink", bad}}}});
    const Expected<Scene> r = loadGltf(c.writeGltf(dir / "bad.gltf"));
    ASSERT_FALSE(r) << bad.dump();
    EXPECT_NE(r.status().message().find("Statue"), std::string::npos) << r.status().message();
    EXPECT_NE(r.status().message().find(bad.begin().key()), std::string::npos) << r.status().message();
  }
}

TEST(SceneLoad, AlphaModesAndCastShadowsFlags) {
  // Issue 46: MASK (with its cutoff) and BLEND are read, not ignored; cast_shadows comes from
  // the node (inherited) over the material's extras.
  TempDir dir;
  GltfBuilder b;
  b.json()["materials"] = nlohmann::json::array(
      {{{"name", "leaf"}, {"alphaMode", "MASK"}, {"alphaCutoff", 0.3}},
       {{"name", "glass"}, {"alphaMode", "BLEND"}, {"extras", {{"lightlink", {{"cast_shadows", false}}}}}},
       {{"name", "wall"}}});
  auto mesh_with = [&](int material) {
    const int acc = b.addVec3(unitTriangle());
    const std::vector<std::uint16_t> idx = {0, 1, 2};
    const int ia = b.addIndicesU16(idx);
    return b.addMesh({{"attributes", {{"POSITION", acc}}}, {"indices", ia}, {"material", material}});
  };
  const int leaf = mesh_with(0), glass = mesh_with(1), wall = mesh_with(2);
  const int n_leaf = b.addNode({{"mesh", leaf}});
  const int n_glass = b.addNode({{"mesh", glass}});
  const int n_glass_on = b.addNode({{"mesh", glass}, {"extras", {{"lightlink", {{"cast_shadows", true}}}}}});
  const int n_parent = b.addNode({{"mesh", wall}, {"extras", {{"lightlink", {{"cast_shadows", false}}}}}});
  const int n_child = b.addNode({{"mesh", wall}}, false);
  b.addChild(n_parent, n_child);
  const Scene scene = loadOk(b.writeGltf(dir / "t.gltf"));
  ASSERT_EQ(scene.materials.size(), 3u);
  EXPECT_EQ(scene.materials[0].alpha_mode, Material::AlphaMode::kMask);
  EXPECT_FLOAT_EQ(scene.materials[0].alpha_cutoff, 0.3f);
  EXPECT_FLOAT_EQ(scene.materials[0].cutoutThreshold(), 0.3f);
  EXPECT_EQ(scene.materials[1].alpha_mode, Material::AlphaMode::kBlend);
  EXPECT_FLOAT_EQ(scene.materials[1].cutoutThreshold(), 0.5f);
  EXPECT_FALSE(scene.materials[1].cast_shadows);
  EXPECT_EQ(scene.materials[2].alpha_mode, Material::AlphaMode::kOpaque);
  for (const MeshInstance& m : scene.meshes) {
    const bool casts = m.gltf_node == n_leaf || m.gltf_node == n_glass_on;
    EXPECT_EQ(m.cast_shadows, casts) << "node " << m.gltf_node;
  }
  EXPECT_EQ(scene.meshes.size(), 5u);
  (void)n_glass;
  (void)n_child;
  GltfBuilder c;
  const int m = c.addTriangles(unitTriangle(), {0, 1, 2});
  c.json()["materials"] = nlohmann::json::array({{{"name", "Veil"}, {"extras", {{"lightlink", {{"cast_shadows", 0}}}}}}});
  c.json()["meshes"][m]["primitives"][0]["material"] = 0;
  c.addNode({{"mesh", m}});
  const Expected<Scene> r = loadGltf(c.writeGltf(dir / "bad.gltf"));
  ASSERT_FALSE(r);
  EXPECT_NE(r.status().message().find("Veil"), std::string::npos) << r.status().message();
  EXPECT_NE(r.status().message().find("cast_shadows"), std::string::npos) << r.status().message();
}

TEST(SceneLoad, ContributeAndReceiveGiFlags) {
  TempDir dir;
  GltfBuilder b;
  b.json()["materials"] = nlohmann::json::array(
      {{{"name", "screen"}, {"extras", {{"lightlink", {{"contribute_gi", false}, {"receive_gi", "off"}}}}}},
       {{"name", "wall"}}});
  auto mesh_with = [&](int material) {
    const int acc = b.addVec3(unitTriangle());
    const std::vector<std::uint16_t> idx = {0, 1, 2};
    const int ia = b.addIndicesU16(idx);
    return b.addMesh({{"attributes", {{"POSITION", acc}}}, {"indices", ia}, {"material", material}});
  };
  const int screen = mesh_with(0), wall = mesh_with(1);
  const int n_screen = b.addNode({{"mesh", screen}});
  const int n_screen_lit = b.addNode(
      {{"mesh", screen}, {"extras", {{"lightlink", {{"contribute_gi", true}, {"receive_gi", "lightmap"}}}}}});
  const int n_wall = b.addNode({{"mesh", wall}});
  const int n_parent = b.addNode({{"mesh", wall}, {"extras", {{"lightlink", {{"receive_gi", "volume"}}}}}});
  const int n_child = b.addNode({{"mesh", wall}}, false);
  b.addChild(n_parent, n_child);
  const int n_probe = b.addNode({{"mesh", wall}, {"extras", {{"lightlink", {{"lightmap", false}}}}}});
  const Scene scene = loadOk(b.writeGltf(dir / "t.gltf"));
  ASSERT_EQ(scene.meshes.size(), 6u);
  for (const MeshInstance& m : scene.meshes) {
    const int n = m.gltf_node;
    EXPECT_EQ(m.contribute_gi, n != n_screen) << "node " << n;
    const ReceiveGi expect = n == n_screen                     ? ReceiveGi::kOff
                             : n == n_parent || n == n_child || n == n_probe ? ReceiveGi::kVolume
                                                                             : ReceiveGi::kLightmap;
    EXPECT_EQ(m.receive_gi, expect) << "node " << n;
    EXPECT_EQ(m.probe_lit, expect != ReceiveGi::kLightmap) << "node " << n;
  }
  (void)n_screen_lit;
  (void)n_wall;
  GltfBuilder c;
  const int m = c.addTriangles(unitTriangle(), {0, 1, 2});
  c.addNode({{"mesh", m}, {"name", "Statue"}, {"extras", {{"lightlink", {{"receive_gi", "sometimes"}}}}}});
  const Expected<Scene> r = loadGltf(c.writeGltf(dir / "bad.gltf"));
  ASSERT_FALSE(r);
  EXPECT_NE(r.status().message().find("Statue"), std::string::npos) << r.status().message();
  EXPECT_NE(r.status().message().find("receive_gi"), std::string::npos) << r.status().message();
}

TEST(SceneLoad, DegenerateTrianglesAreDroppedCountedAndWarnedOncePerMesh) {
  TempDir dir;
  GltfBuilder b;
  const std::vector<glm::vec3> p = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {2, 0, 0}, {0, 0, 0}};
  // good, repeated index, collinear (zero area), coincident positions (0 and 4), good again
  const int mesh = b.addTriangles(p, {0, 1, 2, 0, 0, 1, 0, 1, 3, 0, 4, 2, 2, 0, 1}, "Floor");
  b.addNode({{"mesh", mesh}});
  b.addNode({{"mesh", mesh}, {"translation", {0, 0, 1}}});
  const Scene scene = loadOk(b.writeGltf(dir / "t.gltf"));
  ASSERT_EQ(scene.meshes.size(), 2u);
  EXPECT_EQ(scene.meshes[0].indices, (std::vector<std::uint32_t>{0, 1, 2, 2, 0, 1}));
  EXPECT_EQ(scene.stats.triangles_in, 10u);
  EXPECT_EQ(scene.stats.degenerate_dropped, 6u);
  EXPECT_EQ(scene.triangleCount(), 4u);
  ASSERT_EQ(scene.warnings.size(), 1u);
  EXPECT_NE(scene.warnings[0].find("mesh 0 'Floor'"), std::string::npos) << scene.warnings[0];
  EXPECT_NE(scene.warnings[0].find("6 degenerate"), std::string::npos) << scene.warnings[0];
}

TEST(SceneLoad, InstancesLeftWithoutTrianglesAreRemoved) {
  TempDir dir;
  GltfBuilder b;
  const int good = b.addTriangles(unitTriangle(), {0, 1, 2}, "Good");
  const int flat = b.addTriangles({{0, 0, 0}, {1, 0, 0}, {2, 0, 0}}, {0, 1, 2}, "Sliver");
  b.addNode({{"mesh", good}});
  b.addNode({{"mesh", flat}});
  const Scene scene = loadOk(b.writeGltf(dir / "t.gltf"));
  ASSERT_EQ(scene.meshes.size(), 1u);
  EXPECT_EQ(scene.meshes[0].name, "Good/0");
  EXPECT_EQ(scene.stats.instances_without_triangles, 1u);
  EXPECT_EQ(scene.stats.degenerate_dropped, 1u);
  ASSERT_EQ(scene.warnings.size(), 1u);
  EXPECT_NE(scene.warnings[0].find("mesh 1 'Sliver'"), std::string::npos) << scene.warnings[0];
}

TEST(SceneLoad, TinyButValidTrianglesSurviveAtMillimetreScale) {
  TempDir dir;
  GltfBuilder b;
  // A 1 mm scene whose smallest triangle has 1 um edges: far above 1e-7 of the scale.
  const std::vector<glm::vec3> p = {{0, 0, 0}, {1e-3f, 0, 0}, {0, 1e-3f, 0}, {1e-6f, 0, 0}, {0, 1e-6f, 0}};
  b.addNode({{"mesh", b.addTriangles(p, {0, 1, 2, 0, 3, 4})}});
  const Scene scene = loadOk(b.writeGltf(dir / "t.gltf"));
  EXPECT_EQ(scene.triangleCount(), 2u);
  EXPECT_EQ(scene.stats.degenerate_dropped, 0u);
}

TEST(SceneLoad, LoadTexturesOffKeepsReferencesButSkipsPixels) {
  TempDir dir;
  GltfBuilder b;
  const std::vector<std::uint8_t> img = testing::bmp24(2, 2, std::vector<std::uint8_t>(12, 128));
  b.json()["images"] = {{{"uri", "data:image/bmp;base64," + testing::base64(img.data(), img.size())}}};
  b.json()["textures"] = {{{"source", 0}}};
  b.json()["materials"] = {{{"pbrMetallicRoughness", {{"baseColorTexture", {{"index", 0}}}}}}};
  const int pos = b.addVec3(unitTriangle());
  const int uv = b.addVec2({{0, 0}, {1, 0}, {0, 1}});
  b.addNode({{"mesh", b.addMesh({{"attributes", {{"POSITION", pos}, {"TEXCOORD_0", uv}}}, {"material", 0}})}});
  const std::string path = b.writeGltf(dir / "t.gltf");
  LoadOptions no_textures;
  no_textures.load_textures = false;
  Expected<Scene> scene = loadGltf(path, no_textures);
  ASSERT_TRUE(scene.hasValue()) << scene.status().toString();
  ASSERT_EQ(scene->textures.size(), 1u);
  EXPECT_TRUE(scene->textures[0].rgba8.empty());
  EXPECT_EQ(scene->materials[0].base_color_texture.texture, 0);
  EXPECT_TRUE(scene->warnings.empty());
  const Scene with = loadOk(path);
  ASSERT_EQ(with.textures.size(), 1u);
  EXPECT_EQ(with.textures[0].width, 2);
  EXPECT_EQ(with.textures[0].rgba8.size(), 12u);  // RGB: an opaque material reads no alpha
}

}  // namespace
}  // namespace lightlink::scene
