#include "core/precompute/precompute.h"

#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>

#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include "core/charts/test_meshes.h"
#include "core/common/memory.h"
#include "core/scene/load.h"
#include "tests/common/escaping_scenes.h"
#include "tests/common/testing.h"
#include "tests/precompute/demo_options.h"

namespace lightlink::precompute {
namespace {

Precomputation runDemo(const PrecomputeOptions& o) {
  auto scene = scene::loadGltf(kDemo);
  EXPECT_TRUE(scene) << scene.status().toString();
  auto p = run(*scene, o);
  EXPECT_TRUE(p) << p.status().toString();
  return std::move(p).value();
}

std::vector<char> readFile(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

TEST(Precompute, DemoSceneProducesEveryStructure) {
  const Precomputation p = runDemo(smallOptions());
  EXPECT_EQ(p.surfels.size(), 1024u);
  EXPECT_EQ(p.tree.nodeCount(), 2047u);
  EXPECT_GT(p.lightmap.size(), 100u);
  EXPECT_EQ(p.lightmap_links.cacheCount(), p.lightmap.size());
  // The demo has a dynamic probe, so the grid is planned in.
  EXPECT_TRUE(p.has_grid);
  EXPECT_EQ(p.grid_links.cacheCount(), p.grid.size());
  for (std::size_t c = 0; c < p.lightmap_links.cacheCount(); ++c)
    EXPECT_LE(p.lightmap_links.offsets[c + 1] - p.lightmap_links.offsets[c], 32u);
  const auto report = p.report();
  for (const char* stage : {"unwrap", "surfels", "hierarchy", "bvh", "caches", "owners", "links", "total"})
    EXPECT_TRUE(report["seconds"].contains(stage)) << stage;
  EXPECT_GT(report["links"]["lightmap"]["rays"].get<std::uint64_t>(), 0u);
  EXPECT_GT(report["memory_bytes"]["lightmap_links_projected"].get<std::size_t>(), 0u);
  // Link generation's phases as shares of their sum, and its own work per unit of tracing
  // (benchmark builds; a product build has no probes and no such fields).
  EXPECT_EQ(report["links"]["lightmap"].contains("phase_share"), links::kPhaseProbes);
  if (links::kPhaseProbes) {
    double shares = 0.0;
    for (const auto& [phase, share] : report["links"]["lightmap"]["phase_share"].items()) {
      EXPECT_GT(share.get<double>(), 0.0) << phase;
      shares += share.get<double>();
    }
    EXPECT_NEAR(shares, 1.0, 1e-9);
    EXPECT_EQ(report["links"]["lightmap"]["phase_share"].size(), std::size_t(links::kLinkPhases));
    EXPECT_GT(report["links"]["lightmap"]["own_work_per_trace"].get<double>(), 0.0);
  }
  // Inside a closed-ish room most link rays hit front faces.
  const auto& s = p.lightmap_links.stats;
  EXPECT_GT(double(s.front_hits) / double(s.rays), 0.5);
}

// A daemon that opened and closed a scene keeps none of its freed link arrays: the freed-block
// cache (core/common/memory.h) lives only while a precompute runs.
TEST(Precompute, KeepsNoFreedMemoryOnceTheArtifactIsGone) {
  PrecomputeOptions o = smallOptions();
  o.target_resolution = 128;  // ~10k caches x 64 links: link arrays of several huge pages
  o.links = 64;
  {
    const Precomputation p = runDemo(o);
    EXPECT_GE(p.lightmap_links.node.size() * sizeof(std::uint32_t), kHugePageBytes);
    EXPECT_EQ(cachedHugeBytes(), 0u) << "freed blocks kept after the precompute ended";
  }
  EXPECT_EQ(cachedHugeBytes(), 0u) << "the closed scene's link arrays are kept";
}

TEST(Precompute, GridIsSkippedWithoutDynamicMeshes) {
  auto scene = scene::loadGltf(kDemo);
  ASSERT_TRUE(scene);
  std::erase_if(scene->meshes, [](const scene::MeshInstance& m) { return !m.is_static; });
  auto p = run(*scene, smallOptions());
  ASSERT_TRUE(p) << p.status().toString();
  EXPECT_FALSE(p->has_grid);
  EXPECT_EQ(p->grid.size(), 0u);
  bool noted = false;
  for (const auto& n : p->notes) noted |= n.find("grid caches skipped") != std::string::npos;
  EXPECT_TRUE(noted);
}

TEST(Precompute, ArtifactRoundTripKeepsEveryArray) {
  const Precomputation p = runDemo(smallOptions());
  testing::TempDir dir;
  const std::string path = (dir / "demo.llk").string();
  ASSERT_TRUE(save(p, path, 1234));
  auto loaded = open(path);
  ASSERT_TRUE(loaded) << loaded.status().toString();
  EXPECT_EQ(loaded->file.cacheKey(), 1234u);
  const Precomputation& q = loaded->p;
  EXPECT_EQ(q.surfels.position, p.surfels.position);
  EXPECT_EQ(q.surfels.area, p.surfels.area);
  EXPECT_EQ(q.tree.left, p.tree.left);
  EXPECT_EQ(q.tree.area, p.tree.area);
  EXPECT_EQ(q.surfel_seen, p.surfel_seen);
  EXPECT_EQ(p.surfel_seen.size(), p.surfels.size());
  EXPECT_GT(std::count(p.surfel_seen.begin(), p.surfel_seen.end(), 1), 0);
  EXPECT_EQ(q.lightmap.texel, p.lightmap.texel);
  EXPECT_EQ(q.lightmap.cache_of_texel, p.lightmap.cache_of_texel);
  EXPECT_EQ(q.lightmap.width, p.lightmap.width);
  EXPECT_EQ(q.grid.dims, p.grid.dims);
  EXPECT_EQ(q.dilation.source, p.dilation.source);
  const auto& l = loaded->lightmap_links;
  EXPECT_EQ(l.bands, 3);
  EXPECT_TRUE(std::equal(l.node.begin(), l.node.end(), p.lightmap_links.node.begin(), p.lightmap_links.node.end()));
  EXPECT_TRUE(std::equal(l.coeffs.begin(), l.coeffs.end(), p.lightmap_links.coeffs.begin(),
                         p.lightmap_links.coeffs.end()));
  // Zero copy: the link arrays point into the mapping.
  const auto whole = *loaded->file.bytes("lmlink.node");
  EXPECT_EQ(static_cast<const void*>(l.node.data()), static_cast<const void*>(whole.data()));
}

TEST(Precompute, ArtifactIsDeterministicAcrossThreadCounts) {
  testing::TempDir dir;
  auto write = [&](int threads, const std::string& name) {
    tbb::global_control limit(tbb::global_control::max_allowed_parallelism, threads);
    const Precomputation p = runDemo(smallOptions());
    const std::string path = (dir / name).string();
    EXPECT_TRUE(save(p, path, 7));
    return readFile(path);
  };
  const auto one = write(1, "one.llk");
  const auto two = write(2, "two.llk");
  ASSERT_FALSE(one.empty());
  EXPECT_TRUE(one == two) << "artifacts differ between 1 and 2 threads";
}

TEST(Precompute, RejectsAbsurdOptions) {
  auto scene = scene::loadGltf(kDemo);
  ASSERT_TRUE(scene);
  PrecomputeOptions bad = smallOptions();
  bad.surfels = 0;
  EXPECT_FALSE(run(*scene, bad));
  bad = smallOptions();
  bad.bands = 5;
  auto r = run(*scene, bad);
  ASSERT_FALSE(r);
  EXPECT_NE(r.status().message().find("--bands"), std::string::npos);
  bad = smallOptions();
  bad.texel_size_m = std::nanf("");
  EXPECT_FALSE(run(*scene, bad));
  bad = smallOptions();
  bad.grid_spacing_m = -1.0f;
  EXPECT_FALSE(run(*scene, bad));
}

TEST(Precompute, CacheKeyFollowsSceneAndOptions) {
  auto a = cacheKeyFor(kDemo, smallOptions());
  ASSERT_TRUE(a);
  EXPECT_EQ(*a, *cacheKeyFor(kDemo, smallOptions()));
  PrecomputeOptions other = smallOptions();
  other.links = 64;
  EXPECT_NE(*a, *cacheKeyFor(kDemo, other));
  EXPECT_FALSE(cacheKeyFor("/no/such/scene.gltf", smallOptions()));
}

TEST(Precompute, CacheKeyCoversExternalBuffersAndImages) {
  const std::filesystem::path dir = std::filesystem::path(::testing::TempDir()) / "cache_key_external";
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  auto write = [&](const std::string& name, const std::string& text) {
    std::ofstream(dir / name, std::ios::binary) << text;
  };
  // albedo.png is a base colour (decoded for lighting); normal.png a normal map (never read).
  write("scene.gltf", R"({"asset": {"version": "2.0"}, "buffers": [{"uri": "geo%20a.bin", "byteLength": 4}],
                          "images": [{"uri": "albedo.png"}, {"uri": "data:image/png;base64,AAAA"}, {"uri": "normal.png"}],
                          "textures": [{"source": 0}, {"source": 2}],
                          "materials": [{"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}},
                                         "normalTexture": {"index": 1}}],
                          "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "material": 0}]}]})");
  write("normal.png", "normal1");
  write("geo a.bin", "abcd");
  write("albedo.png", "png1");
  const std::string scene = (dir / "scene.gltf").string();
  auto a = cacheKeyFor(scene, smallOptions());
  ASSERT_TRUE(a) << a.status().message();
  write("geo a.bin", "abce");  // same size, other geometry
  auto b = cacheKeyFor(scene, smallOptions());
  ASSERT_TRUE(b);
  EXPECT_NE(*a, *b) << "an edited .bin must not reuse the artifact";
  write("albedo.png", "png2");
  auto c = cacheKeyFor(scene, smallOptions());
  ASSERT_TRUE(c);
  EXPECT_NE(*b, *c) << "an edited texture must not reuse the artifact";
  EXPECT_EQ(*c, *cacheKeyFor(scene, smallOptions()));
  // The normal map changes nothing lightlink computes: same key, edited or even missing.
  write("normal.png", "normal2");
  EXPECT_EQ(*c, *cacheKeyFor(scene, smallOptions())) << "a normal map's bytes must not change the key";
  std::filesystem::remove(dir / "normal.png");
  EXPECT_EQ(*c, *cacheKeyFor(scene, smallOptions()));
  // A missing texture is keyed as missing (the loader only warns); a missing buffer fails.
  std::filesystem::remove(dir / "albedo.png");
  auto no_texture = cacheKeyFor(scene, smallOptions());
  ASSERT_TRUE(no_texture) << no_texture.status().message();
  EXPECT_NE(*c, *no_texture);
  std::filesystem::remove(dir / "geo a.bin");
  auto missing = cacheKeyFor(scene, smallOptions());
  ASSERT_FALSE(missing);
  EXPECT_NE(missing.status().message().find("buffers[0].uri"), std::string::npos) << missing.status().message();
}

// An OBJ's materials and textures live in other files: editing the .mtl or a map_Kd image
// must not reuse the artifact, a missing texture is keyed as missing, and an mtllib outside
// the folder is refused as the loader refuses it (core/scene/obj_files.h).
TEST(Precompute, CacheKeyCoversAnObjsMtlAndTextures) {
  lightlink::testing::TempDir dir;
  std::filesystem::create_directories(dir.path() / "level");
  auto write = [&](const std::string& name, const std::string& text) {
    std::ofstream(dir.path() / name, std::ios::binary) << text;
  };
  write("level/scene.obj", "mtllib scene.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl red\nf 1 2 3\n");
  write("level/scene.mtl", "newmtl red\nKd 0.5 0 0\nmap_Kd -s 1 1 1 tex\\red.png\n");
  std::filesystem::create_directories(dir.path() / "level/tex");
  write("level/tex/red.png", "png1");
  const std::string scene = (dir.path() / "level/scene.obj").string();
  auto a = cacheKeyFor(scene, smallOptions());
  ASSERT_TRUE(a) << a.status().message();
  EXPECT_EQ(*a, *cacheKeyFor(scene, smallOptions()));
  write("level/scene.mtl", "newmtl red\nKd 0.6 0 0\nmap_Kd -s 1 1 1 tex\\red.png\n");
  auto b = cacheKeyFor(scene, smallOptions());
  ASSERT_TRUE(b);
  EXPECT_NE(*a, *b) << "an edited .mtl must not reuse the artifact";
  write("level/tex/red.png", "png2");
  auto c = cacheKeyFor(scene, smallOptions());
  ASSERT_TRUE(c);
  EXPECT_NE(*b, *c) << "an edited map_Kd image must not reuse the artifact";
  std::filesystem::remove(dir.path() / "level/tex/red.png");
  auto d = cacheKeyFor(scene, smallOptions());
  ASSERT_TRUE(d) << d.status().message();
  EXPECT_NE(*c, *d);
  write("outside.mtl", "newmtl red\nKd 1 1 1\n");
  write("level/scene.obj", "mtllib ../outside.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl red\nf 1 2 3\n");
  auto refused = cacheKeyFor(scene, smallOptions());
  ASSERT_FALSE(refused) << "hashed a file outside the scene's folder";
  EXPECT_NE(refused.status().message().find("outside.mtl"), std::string::npos) << refused.status().message();
}

// The key reads the scene's files under the loader's rules (core/scene/scene_files.h).
TEST(Precompute, CacheKeyReadsOnlyInsideTheSceneFolder) {
  lightlink::testing::TempDir dir;
  const std::string scene = lightlink::testing::writeEscapingScene(dir.path(), lightlink::testing::Escape::kDotDot);
  auto refused = cacheKeyFor(scene, smallOptions());
  ASSERT_FALSE(refused) << "hashed a file outside the scene's folder";
  EXPECT_NE(refused.status().message().find("buffers[0].uri"), std::string::npos) << refused.status().message();
  scene::FileAccess allow;
  allow.allow_outside_folder = true;
  EXPECT_TRUE(cacheKeyFor(scene, smallOptions(), allow));
}


// A downloaded scene often lacks some texture files: the loader warns and the material uses
// its factor, so the key must not fail on them either. Restoring the file changes the key;
// an image URI that leaves the folder is still refused.
TEST(Precompute, CacheKeyKeysAMissingImageAsMissing) {
  lightlink::testing::TempDir dir;
  lightlink::testing::writeFile(dir / "geo.bin", lightlink::testing::triangleBin());
  auto withImage = [](const std::string& uri) {
    // The image is the triangle's base colour: what the loader decodes and the key hashes.
    std::string gltf = lightlink::testing::triangleGltf("geo.bin");
    gltf.insert(1, fmt::format(R"("images": [{{"uri": "{}"}}], "textures": [{{"source": 0}}],
                                  "materials": [{{"pbrMetallicRoughness": {{"baseColorTexture": {{"index": 0}}}}}}], )",
                               uri));
    const std::string attributes = R"("attributes": {"POSITION": 0},)";
    gltf.insert(gltf.find(attributes) + attributes.size(), R"( "material": 0,)");
    return gltf;
  };
  const std::string scene = lightlink::testing::writeFile(dir / "scene.gltf", withImage("albedo.png"));
  auto missing = cacheKeyFor(scene, smallOptions());
  ASSERT_TRUE(missing) << missing.status().message();
  auto loaded = scene::loadGltf(scene);
  ASSERT_TRUE(loaded) << "the loader must take the scene too: " << loaded.status().message();
  lightlink::testing::writeFile(dir / "albedo.png", "not really a png");
  auto present = cacheKeyFor(scene, smallOptions());
  ASSERT_TRUE(present) << present.status().message();
  EXPECT_NE(*missing, *present);
  lightlink::testing::writeFile(dir / "scene.gltf", withImage("../albedo.png"));
  auto escaping = cacheKeyFor(scene, smallOptions());
  ASSERT_FALSE(escaping);
  EXPECT_NE(escaping.status().message().find("images[0].uri"), std::string::npos) << escaping.status().message();
}

TEST(Precompute, ObjectsTooSmallForTheLightmapGetAGridAroundThem) {
  namespace tm = charts::test_meshes;
  scene::MeshInstance room = tm::cube(4.0f, 2), pebble = tm::sphere(0.01f, 8, 4);
  for (glm::vec3& q : pebble.positions) q += glm::vec3(0.5f, -1.9f, 0.5f);
  pebble.name = "pebble";
  scene::Scene scene = tm::makeScene({room, pebble});
  PrecomputeOptions o = smallOptions();
  o.texel_budget = 2048;  // ~0.2 m texels: the 2 cm pebble is far below 2x2 texels
  auto p = run(scene, o);
  ASSERT_TRUE(p) << p.status().toString();
  EXPECT_EQ(p->atlas.probe_lit, std::vector<std::uint32_t>{1});
  EXPECT_TRUE(p->has_grid);  // no dynamic mesh: the grid is there for the pebble
  // A volume around the pebble (one spacing of margin), not the whole room.
  const glm::vec3 hi = p->grid.origin + glm::vec3(p->grid.dims - 1) * p->grid.spacing_m;
  EXPECT_TRUE(glm::all(glm::lessThanEqual(p->grid.origin, glm::vec3(0.49f, -1.91f, 0.49f))));
  EXPECT_TRUE(glm::all(glm::greaterThanEqual(hi, glm::vec3(0.51f, -1.89f, 0.51f))));
  EXPECT_LT(glm::length(hi - p->grid.origin), 0.5f * scene.scale);  // the room is 4 m wide
  bool noted = false;
  for (const std::string& n : p->notes) noted |= n.find("probe-lit") != std::string::npos;
  EXPECT_TRUE(noted);
  const auto report = p->report();
  EXPECT_EQ(report["counts"]["probe_lit_meshes"], 1u);
  EXPECT_EQ(report["probe_lit"], nlohmann::ordered_json::array({"pebble"}));
}

}  // namespace
}  // namespace lightlink::precompute
