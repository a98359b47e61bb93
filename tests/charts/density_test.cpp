// The lightmap density model (unwrap.h): the texel-size rule from a texel budget, pages
// (charts packed onto as many square pages as needed, none straddling two), charts larger
// than a page scaled down, per-mesh lightmap_scale, objects too small for the lightmap
// made probe-lit, and existing TEXCOORD_1 kept at the resolution it was packed for.
#include <gtest/gtest.h>

#include <cmath>

#include "core/charts/test_meshes.h"
#include "core/charts/unwrap.h"
#include "tests/charts/atlas_oracle.h"

namespace lightlink::charts {
namespace {

namespace tm = test_meshes;

void expectValid(const scene::Scene& scene, const UnwrapResult& r) {
  const testing::OracleResult oracle = testing::checkWithOracle(scene, r.atlas);
  EXPECT_EQ(oracle.chart_overlap_texels + oracle.center_overlaps + oracle.gutter_violations + oracle.flipped +
                oracle.out_of_range,
            0u)
      << oracle.first_problem;
}

scene::MeshInstance moved(scene::MeshInstance m, glm::vec3 offset, const char* name) {
  for (glm::vec3& p : m.positions) p += offset;
  m.name = name;
  return m;
}

// `n` separate unit-normal quads of side `size` on a grid: n charts.
scene::MeshInstance quads(int n, float size, float spacing) {
  scene::MeshInstance m;
  m.name = "quads";
  const int row = static_cast<int>(std::ceil(std::sqrt(double(n))));
  for (int i = 0; i < n; ++i) {
    const glm::vec3 o(float(i % row) * spacing, 0.0f, float(i / row) * spacing);
    const auto b = static_cast<std::uint32_t>(m.positions.size());
    for (glm::vec3 c : {glm::vec3(0, 0, 0), glm::vec3(0, 0, 1), glm::vec3(1, 0, 1), glm::vec3(1, 0, 0)}) {
      m.positions.push_back(o + c * size);
      m.normals.emplace_back(0.0f, 1.0f, 0.0f);
    }
    m.indices.insert(m.indices.end(), {b, b + 1, b + 2, b, b + 2, b + 3});
  }
  return m;
}

TEST(Density, TexelBudgetGivesAboutThatManyTexels) {
  scene::Scene scene = tm::makeScene({tm::sphere(1.0f, 32, 16), moved(tm::torus(1.0f, 0.3f, 32, 12), {3, 0, 0}, "torus"),
                                      moved(tm::cube(1.5f, 2), {-3, 0, 0}, "cube")});
  UnwrapOptions o;
  o.texel_budget = 20000;
  Expected<UnwrapResult> r = unwrap(scene, o);
  ASSERT_TRUE(r) << r.status().toString();
  const double covered = r->report.utilisation * double(r->atlas.resolution) * r->atlas.height();
  EXPECT_GT(covered, 0.7 * 20000) << r->report.toText();
  EXPECT_LT(covered, 1.3 * 20000) << r->report.toText();
  EXPECT_EQ(r->atlas.pages, 1);
  expectValid(scene, *r);
}

TEST(Density, ChartsGoOntoAsManyPagesAsNeededNeverStraddlingTwo) {
  scene::Scene scene = tm::makeScene({tm::planeWithHoles(4.0f, 9), moved(tm::cube(2.0f, 2), {5, 0, 0}, "cube"),
                                      moved(tm::sphere(1.0f, 24, 12), {-5, 0, 0}, "sphere")});
  UnwrapOptions o;
  o.texel_size_m = 0.05f;
  o.max_atlas = 64;
  Expected<UnwrapResult> r = unwrap(scene, o);
  ASSERT_TRUE(r) << r.status().toString();
  EXPECT_EQ(r->atlas.resolution, 64);
  EXPECT_GT(r->atlas.pages, 2) << r->report.toText();
  EXPECT_EQ(r->report.pages, r->atlas.pages);
  expectValid(scene, *r);
  // Every triangle lies on one page: its v range in page units does not cross an integer.
  for (const scene::MeshInstance& mesh : scene.meshes)
    for (std::size_t t = 0; t < mesh.triangleCount(); ++t) {
      float lo = 1e9f, hi = -1e9f;
      for (int k = 0; k < 3; ++k) {
        const float v = mesh.uv1[mesh.indices[3 * t + k]].y * float(r->atlas.pages);
        lo = std::min(lo, v);
        hi = std::max(hi, v);
      }
      ASSERT_EQ(std::floor(lo), std::floor(hi - 1e-6f)) << mesh.name << " triangle " << t;
    }
  // The same charts at the same size fit one 1024 page: one page when one is enough.
  scene::Scene again = tm::makeScene({tm::planeWithHoles(4.0f, 9), moved(tm::cube(2.0f, 2), {5, 0, 0}, "cube"),
                                      moved(tm::sphere(1.0f, 24, 12), {-5, 0, 0}, "sphere")});
  o.max_atlas = 1024;
  Expected<UnwrapResult> one = unwrap(again, o);
  ASSERT_TRUE(one);
  EXPECT_EQ(one->atlas.pages, 1);
  EXPECT_LE(one->atlas.resolution, 512);
  // A page cap raises the texel size until the charts fit, and says so.
  scene::Scene capped = tm::makeScene({tm::planeWithHoles(4.0f, 9), moved(tm::cube(2.0f, 2), {5, 0, 0}, "cube"),
                                       moved(tm::sphere(1.0f, 24, 12), {-5, 0, 0}, "sphere")});
  o.max_atlas = 64;
  o.max_pages = 2;
  Expected<UnwrapResult> two = unwrap(capped, o);
  ASSERT_TRUE(two) << two.status().toString();
  EXPECT_LE(two->atlas.pages, 2);
  EXPECT_GT(two->atlas.texel_size_m, 0.05f);
  ASSERT_FALSE(two->report.warnings.empty());
  EXPECT_NE(two->report.warnings.back().find("--max-pages"), std::string::npos);
  expectValid(capped, *two);
}

TEST(Density, AChartLargerThanAPageIsScaledDownWithAWarning) {
  scene::MeshInstance floor = tm::planeWithHoles(40.0f, 1);
  floor.name = "floor";
  scene::Scene scene = tm::makeScene({floor});
  UnwrapOptions o;
  o.texel_size_m = 0.1f;  // 400 texels a side
  o.max_atlas = 128;
  Expected<UnwrapResult> r = unwrap(scene, o);
  ASSERT_TRUE(r) << r.status().toString();
  ASSERT_FALSE(r->report.warnings.empty());
  EXPECT_NE(r->report.warnings[0].find("'floor'"), std::string::npos) << r->report.warnings[0];
  EXPECT_NE(r->report.warnings[0].find("scaled down"), std::string::npos) << r->report.warnings[0];
  EXPECT_EQ(r->atlas.resolution, 128);
  expectValid(scene, *r);
}

TEST(Density, LightmapScaleMultipliesTheTexelsOfOneMesh) {
  scene::MeshInstance a = tm::cube(1.0f, 1), b = moved(tm::cube(1.0f, 1), {3, 0, 0}, "dense");
  b.lightmap_scale = 2.0f;
  scene::Scene scene = tm::makeScene({a, b});
  UnwrapOptions o;
  o.texel_size_m = 0.05f;
  Expected<UnwrapResult> r = unwrap(scene, o);
  ASSERT_TRUE(r) << r.status().toString();
  // uv area of each mesh in texels: b's faces have twice the texels per side.
  auto texels = [&](const scene::MeshInstance& m) {
    double sum = 0.0;
    const glm::dvec2 size(r->atlas.resolution, r->atlas.height());
    for (std::size_t t = 0; t < m.triangleCount(); ++t) {
      const glm::dvec2 p = glm::dvec2(m.uv1[m.indices[3 * t]]) * size, q = glm::dvec2(m.uv1[m.indices[3 * t + 1]]) * size,
                       w = glm::dvec2(m.uv1[m.indices[3 * t + 2]]) * size;
      sum += 0.5 * std::abs((q.x - p.x) * (w.y - p.y) - (q.y - p.y) * (w.x - p.x));
    }
    return sum;
  };
  EXPECT_NEAR(texels(scene.meshes[1]) / texels(scene.meshes[0]), 4.0, 0.05);
  EXPECT_LT(r->report.max_area_stretch, 1.05);  // stretch is measured against each mesh's own density
  expectValid(scene, *r);
}

TEST(Density, ObjectsTooSmallForTheLightmapAreProbeLit) {
  scene::MeshInstance floor = tm::planeWithHoles(10.0f, 1), pebble = moved(tm::sphere(0.01f, 8, 4), {1, 0.1f, 1}, "pebble");
  floor.name = "floor";
  scene::MeshInstance flagged = moved(tm::cube(1.0f, 1), {-3, 0, 0}, "flagged");
  flagged.probe_lit = true;  // node extras {"lightlink": {"lightmap": false}}
  scene::Scene scene = tm::makeScene({floor, pebble, flagged});
  UnwrapOptions o;
  o.texel_budget = 4096;  // ~0.15 m texels: the 2 cm pebble is far below 2x2 texels
  Expected<UnwrapResult> r = unwrap(scene, o);
  ASSERT_TRUE(r) << r.status().toString();
  EXPECT_EQ(r->atlas.probe_lit, (std::vector<std::uint32_t>{1, 2}));
  EXPECT_TRUE(scene.meshes[1].probe_lit);
  EXPECT_TRUE(scene.meshes[1].uv1.empty());
  EXPECT_TRUE(scene.meshes[2].uv1.empty());
  EXPECT_FALSE(scene.meshes[0].uv1.empty());
  EXPECT_EQ(r->report.probe_lit_meshes, 2u);
  EXPECT_EQ(r->report.probe_lit, (std::vector<std::string>{"pebble", "flagged"}));
  expectValid(scene, *r);
}

TEST(Density, TenThousandTinyChartsFitTheBudget) {
  scene::Scene scene = tm::makeScene({quads(10000, 0.05f, 0.2f)});
  UnwrapOptions o;
  o.texel_budget = 32768;
  o.probe_lit_small = false;  // one mesh of many charts: every chart must be laid out
  Expected<UnwrapResult> r = unwrap(scene, o);
  ASSERT_TRUE(r) << r.status().toString();
  EXPECT_EQ(r->report.charts, 10000);
  EXPECT_EQ(r->atlas.pages, 1);
  expectValid(scene, *r);
}

TEST(ExistingUv, PackedAt1024KeepsItsResolution) {
  scene::Scene scene = tm::makeScene({tm::sphere(1.0f, 24, 12), moved(tm::cube(1.0f, 2), {3, 0, 0}, "cube")});
  UnwrapOptions pack;
  pack.resolution = 1024;
  ASSERT_TRUE(unwrap(scene, pack));  // a layout packed for 1024^2 with a 2-texel gutter
  const scene::Scene packed = scene;
  Expected<UnwrapResult> kept = unwrap(scene, {});
  ASSERT_TRUE(kept) << kept.status().toString();
  EXPECT_FALSE(kept->report.generated) << kept->report.toText();
  EXPECT_EQ(kept->atlas.resolution, 1024);
  EXPECT_EQ(scene.meshes[0].uv1, packed.meshes[0].uv1);
}

TEST(ExistingUv, AutoRegeneratesOverlappingUvWithAWarning) {
  scene::MeshInstance a = tm::cube(1.0f, 1);
  a.uv1 = a.uv0;  // every face over the whole square
  scene::Scene scene = tm::makeScene({a});
  UnwrapOptions o;
  o.texel_budget = 4096;
  Expected<UnwrapResult> r = unwrap(scene, o);
  ASSERT_TRUE(r) << r.status().toString();
  EXPECT_TRUE(r->report.generated);
  ASSERT_FALSE(r->report.warnings.empty());
  EXPECT_NE(r->report.warnings[0].find("regenerated"), std::string::npos) << r->report.warnings[0];
  expectValid(scene, *r);
}

}  // namespace
}  // namespace lightlink::charts
