// unwrap() on procedural meshes: the atlas invariants (no overlap, gutter, no flips,
// bounded stretch) checked by an independent oracle, the option checks, the policy for
// existing TEXCOORD_1, and determinism.
#include <gtest/gtest.h>

#include <cstring>
#include <functional>

#include <nlohmann/json.hpp>
#include <tbb/global_control.h>

#include "core/charts/rasterize.h"
#include "core/charts/test_meshes.h"
#include "core/charts/unwrap.h"
#include "tests/charts/atlas_oracle.h"

namespace lightlink::charts {
namespace {

namespace tm = test_meshes;

struct Shape {
  const char* name;
  std::function<scene::MeshInstance()> make;
};

const Shape kShapes[] = {
    {"sphere", [] { return tm::sphere(1.0f, 48, 24); }},
    {"torus", [] { return tm::torus(1.0f, 0.35f, 64, 24); }},
    {"cube", [] { return tm::cube(2.0f, 4); }},
    {"plane_with_holes", [] { return tm::planeWithHoles(4.0f, 33); }},
};

class UnwrapShapes : public ::testing::TestWithParam<Shape> {};

TEST_P(UnwrapShapes, AtlasIsValidAtTargetResolution) {
  scene::Scene scene = tm::makeScene({GetParam().make()});
  const std::size_t triangles_in = scene.meshes[0].triangleCount();
  UnwrapOptions options;
  options.resolution = 512;
  Expected<UnwrapResult> result = unwrap(scene, options);
  ASSERT_TRUE(result) << result.status().toString();
  const UnwrapReport& report = result->report;
  SCOPED_TRACE(report.toText());
  const scene::MeshInstance& mesh = scene.meshes[0];

  EXPECT_TRUE(report.generated);
  EXPECT_EQ(report.resolution, 512);
  EXPECT_EQ(mesh.triangleCount(), triangles_in);  // nothing degenerate in these meshes
  ASSERT_EQ(mesh.uv1.size(), mesh.positions.size());
  ASSERT_EQ(mesh.normals.size(), mesh.positions.size());
  ASSERT_EQ(result->atlas.meshes[0].source_vertex.size(), mesh.positions.size());
  ASSERT_EQ(result->atlas.meshes[0].triangle_chart.size(), mesh.triangleCount());

  const testing::OracleResult oracle = testing::checkWithOracle(scene, result->atlas);
  EXPECT_EQ(oracle.chart_overlap_texels, 0u) << oracle.first_problem;
  EXPECT_EQ(oracle.center_overlaps, 0u) << oracle.first_problem;
  EXPECT_EQ(oracle.gutter_violations, 0u) << oracle.first_problem;
  EXPECT_EQ(oracle.flipped, 0u) << oracle.first_problem;
  EXPECT_EQ(oracle.out_of_range, 0u);
  // The library's own banded check agrees with the oracle.
  EXPECT_EQ(report.overlaps, 0u);
  EXPECT_EQ(report.gutter_violations, 0u);
  EXPECT_EQ(report.flipped, 0u);
  EXPECT_DOUBLE_EQ(report.utilisation, static_cast<double>(oracle.covered) / (512.0 * 512.0));
  // Stretch within the limit (float uv1 may add a hair).
  EXPECT_LE(report.max_area_stretch, options.max_stretch * 1.001);
  EXPECT_GE(report.mean_area_stretch, 1.0);
  EXPECT_LT(report.mean_area_stretch, 1.2);
  EXPECT_GT(report.utilisation, 0.3);
  // Seams split vertices but every new vertex is a copy of an original one.
  for (std::size_t v = 0; v < mesh.positions.size(); ++v) {
    const std::uint32_t src = result->atlas.meshes[0].source_vertex[v];
    ASSERT_EQ(mesh.positions[v], GetParam().make().positions[src]);
  }
}

INSTANTIATE_TEST_SUITE_P(Shapes, UnwrapShapes, ::testing::ValuesIn(kShapes),
                         [](const auto& info) { return std::string(info.param.name); });

TEST(Unwrap, CubeWithHardEdgesGivesSixPlanarCharts) {
  scene::Scene scene = tm::makeScene({tm::cube(1.0f, 3)});
  UnwrapOptions options;
  options.resolution = 256;
  Expected<UnwrapResult> result = unwrap(scene, options);
  ASSERT_TRUE(result) << result.status().toString();
  EXPECT_EQ(result->report.charts, 6);
  EXPECT_EQ(result->report.planar_charts, 6u);
  EXPECT_NEAR(result->report.max_area_stretch, 1.0, 1e-3);
  EXPECT_NEAR(result->report.max_angle_distortion, 1.0, 1e-3);
  // Six squares with gutters pack well.
  EXPECT_GT(result->report.utilisation, 0.6) << result->report.toText();
}

TEST(Unwrap, GutterIsRespectedForWideGutters) {
  scene::Scene scene = tm::makeScene({tm::sphere(1.0f, 24, 12), tm::cube(1.0f, 1)});
  scene.meshes[1].positions[0].x += 0.0f;
  UnwrapOptions options;
  options.resolution = 256;
  options.gutter_texels = 6;
  Expected<UnwrapResult> result = unwrap(scene, options);
  ASSERT_TRUE(result) << result.status().toString();
  const testing::OracleResult oracle = testing::checkWithOracle(scene, result->atlas);
  EXPECT_EQ(oracle.gutter_violations, 0u) << oracle.first_problem;
  EXPECT_EQ(oracle.chart_overlap_texels, 0u) << oracle.first_problem;
  // The border strip of `gutter` texels stays empty.
  for (const scene::MeshInstance& mesh : scene.meshes)
    for (const glm::vec2& t : mesh.uv1) {
      EXPECT_GE(t.x * 256.0f, 6.0f);
      EXPECT_GE(t.y * 256.0f, 6.0f);
      EXPECT_LE(t.x * 256.0f, 250.0f);
      EXPECT_LE(t.y * 256.0f, 250.0f);
    }
}

TEST(Unwrap, TexelSizeIsHonouredAndPicksPowerOfTwo) {
  scene::Scene scene = tm::makeScene({tm::cube(1.0f, 2)});  // 6 m^2
  UnwrapOptions options;
  options.texel_size_m = 0.01f;  // each face ~100x100 texels
  Expected<UnwrapResult> result = unwrap(scene, options);
  ASSERT_TRUE(result) << result.status().toString();
  EXPECT_EQ(result->report.texel_size_m, 0.01f);
  EXPECT_EQ(result->report.resolution, 512);  // 6 faces of ~103^2 need more than 256^2
  // One face: 1 m wide -> 100 texels in uv1.
  const scene::MeshInstance& mesh = scene.meshes[0];
  float umin = 1, umax = 0;
  for (std::size_t t = 0; t < 2 * 4; ++t)  // the first face's 8 triangles
    for (int k = 0; k < 3; ++k) {
      const glm::vec2 uv = mesh.uv1[mesh.indices[3 * t + k]];
      umin = std::min({umin, uv.x, uv.y});
      umax = std::max({umax, uv.x, uv.y});
    }
  EXPECT_NEAR((umax - umin) * 512.0f, 100.0f, 0.5f);
}

TEST(Unwrap, InvalidParametersAreRejectedWithAMessage) {
  scene::Scene scene = tm::makeScene({tm::cube(1.0f, 1)});
  auto rejects = [&](UnwrapOptions o, const char* needle) {
    Expected<UnwrapResult> r = unwrap(scene, o);
    ASSERT_FALSE(r);
    EXPECT_EQ(r.status().code(), Code::kInvalidInput);
    EXPECT_NE(r.status().message().find(needle), std::string::npos) << r.status().message();
  };
  UnwrapOptions o;
  o.texel_size_m = 0.0f;
  rejects(o, "texel size");
  o.texel_size_m = -1.0f;
  rejects(o, "texel size");
  o = {};
  o.resolution = 0;
  rejects(o, "resolution");
  o.resolution = 16385;
  rejects(o, "resolution");
  o = {};
  o.gutter_texels = -1;
  rejects(o, "gutter");
  o = {};
  o.max_stretch = 0.5f;
  rejects(o, "stretch");
  o = {};
  o.texel_size_m = 1.0f;  // 1 m texels: the 1 m cube's faces are 2 texels, fine...
  o.resolution = 4;       // ...but a 4x4 page is all gutter
  rejects(o, "no room");
  o = {};
  o.max_atlas = 8;
  rejects(o, "max-atlas");
  // Nothing was modified by the rejected calls.
  EXPECT_TRUE(scene.meshes[0].uv1.empty());
}

TEST(Unwrap, ExistingLightmapUvIsKeptBitExactlyAndChecked) {
  scene::MeshInstance a = tm::cube(1.0f, 1), b = tm::planeWithHoles(2.0f, 5);
  // Deliberately bad uv1: a's are uv0 (every face over the whole square: overlaps),
  // b's go outside [0, 1].
  a.uv1 = a.uv0;
  for (const glm::vec2& t : b.uv0) b.uv1.push_back(t * 1.5f - 0.1f);
  scene::Scene scene = tm::makeScene({a, b});
  const scene::Scene before = scene;
  UnwrapOptions keep;
  keep.uv_mode = UvMode::kKeep;
  Expected<UnwrapResult> result = unwrap(scene, keep);
  ASSERT_TRUE(result) << result.status().toString();
  EXPECT_FALSE(result->report.generated);
  for (std::size_t m = 0; m < 2; ++m) {
    ASSERT_EQ(scene.meshes[m].uv1.size(), before.meshes[m].uv1.size());
    EXPECT_EQ(std::memcmp(scene.meshes[m].uv1.data(), before.meshes[m].uv1.data(),
                          scene.meshes[m].uv1.size() * sizeof(glm::vec2)), 0);
    EXPECT_EQ(scene.meshes[m].indices, before.meshes[m].indices);
    EXPECT_TRUE(result->atlas.meshes[m].source_vertex.empty());
  }
  EXPECT_GT(result->report.overlaps, 0u);
  EXPECT_GT(result->report.out_of_range, 0u);
  EXPECT_GE(result->report.warnings.size(), 2u) << result->report.toText();
}

TEST(Unwrap, MixedSceneRegeneratesAllStaticMeshes) {
  scene::MeshInstance a = tm::cube(1.0f, 1), b = tm::sphere(0.5f, 16, 8), dynamic = tm::torus(1.0f, 0.2f, 8, 6);
  a.uv1 = a.uv0;
  dynamic.is_static = false;
  scene::Scene scene = tm::makeScene({a, b, dynamic});
  Expected<UnwrapResult> result = unwrap(scene, {});
  ASSERT_TRUE(result) << result.status().toString();
  EXPECT_TRUE(result->report.generated);
  EXPECT_EQ(result->report.meshes, 2);
  ASSERT_EQ(result->report.warnings.size(), 1u);
  EXPECT_NE(result->report.warnings[0].find("replaced"), std::string::npos);
  EXPECT_NE(scene.meshes[0].uv1, a.uv1);
  EXPECT_FALSE(scene.meshes[1].uv1.empty());
  EXPECT_TRUE(scene.meshes[2].uv1.empty());  // dynamic: untouched
  EXPECT_EQ(scene.meshes[2].positions, dynamic.positions);
  const testing::OracleResult oracle = testing::checkWithOracle(scene, result->atlas);
  EXPECT_EQ(oracle.chart_overlap_texels + oracle.center_overlaps + oracle.flipped, 0u) << oracle.first_problem;
}

TEST(Unwrap, KeepExistingFalseRegenerates) {
  scene::MeshInstance a = tm::cube(1.0f, 1);
  a.uv1 = a.uv0;
  scene::Scene scene = tm::makeScene({a});
  UnwrapOptions options;
  options.uv_mode = UvMode::kGenerate;
  Expected<UnwrapResult> result = unwrap(scene, options);
  ASSERT_TRUE(result);
  EXPECT_TRUE(result->report.generated);
  EXPECT_EQ(result->report.overlaps, 0u);
}

TEST(Unwrap, IsDeterministicAtAnyThreadCount) {
  auto run = [] {
    scene::Scene scene =
        tm::makeScene({tm::sphere(1.0f, 40, 20), tm::torus(2.0f, 0.5f, 48, 16), tm::planeWithHoles(5.0f, 21)});
    Expected<UnwrapResult> result = unwrap(scene, {});
    EXPECT_TRUE(result);
    return scene;
  };
  const scene::Scene a = run();
  scene::Scene b;
  {
    tbb::global_control one_thread(tbb::global_control::max_allowed_parallelism, 1);
    b = run();
  }
  for (std::size_t m = 0; m < a.meshes.size(); ++m) {
    ASSERT_EQ(a.meshes[m].uv1.size(), b.meshes[m].uv1.size());
    EXPECT_EQ(std::memcmp(a.meshes[m].uv1.data(), b.meshes[m].uv1.data(), a.meshes[m].uv1.size() * sizeof(glm::vec2)),
              0);
    EXPECT_EQ(a.meshes[m].indices, b.meshes[m].indices);
  }
}

TEST(Unwrap, DefaultFillsTheTargetResolution) {
  scene::Scene scene = tm::makeScene({tm::cube(1.0f, 2), tm::sphere(0.7f, 32, 16)});
  UnwrapOptions options;
  options.target_resolution = 256;
  Expected<UnwrapResult> result = unwrap(scene, options);
  ASSERT_TRUE(result) << result.status().toString();
  EXPECT_EQ(result->report.resolution, 256);
  // The texel size was searched until the packing fills the atlas height.
  EXPECT_GT(result->report.utilisation, 0.6) << result->report.toText();
  EXPECT_FLOAT_EQ(result->atlas.texel_size_m, result->report.texel_size_m);
}

TEST(Unwrap, ReportIsCompleteAsJsonAndText) {
  scene::Scene scene = tm::makeScene({tm::torus(1.0f, 0.3f, 32, 12)});
  Expected<UnwrapResult> result = unwrap(scene, {});
  ASSERT_TRUE(result);
  const UnwrapReport& r = result->report;
  const nlohmann::json j = r.toJson();
  EXPECT_EQ(j.at("charts").get<int>(), r.charts);
  EXPECT_EQ(j.at("overlaps").get<std::size_t>(), 0u);
  EXPECT_DOUBLE_EQ(j.at("utilisation").get<double>(), r.utilisation);
  EXPECT_DOUBLE_EQ(j.at("max_area_stretch").get<double>(), r.max_area_stretch);
  EXPECT_GE(j.at("texels_per_chart").at("max").get<std::size_t>(), j.at("texels_per_chart").at("min").get<std::size_t>());
  EXPECT_GT(j.at("seconds").get<double>(), 0.0);
  const std::string text = r.toText();
  EXPECT_NE(text.find("utilisation"), std::string::npos);
  EXPECT_NE(text.find("overlaps     0"), std::string::npos) << text;
  EXPECT_GT(r.texels_per_chart_min, 0u);
}


}  // namespace
}  // namespace lightlink::charts
