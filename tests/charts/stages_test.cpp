// The stages one by one: welding and the non-manifold split, charting borders, LSCM on a
// curved patch, the distortion measure, packing.
#include <gtest/gtest.h>

#include <cmath>
#include <numeric>

#include "core/charts/flatten.h"
#include "core/charts/mesh_prep.h"
#include "core/charts/pack.h"
#include "core/charts/segment.h"
#include "core/charts/test_meshes.h"
#include "core/charts/unwrap.h"
#include "tests/charts/atlas_oracle.h"

namespace lightlink::charts {
namespace {

namespace tm = test_meshes;

TEST(MeshPrep, WeldsSeamsAndKeepsEveryFace) {
  const scene::MeshInstance sphere = tm::sphere(1.0f, 16, 8);
  const PreparedMesh pm = prepareMesh(sphere, 1e-6);
  // 16 x 9 grid vertices with a duplicated seam column and 16 copies of each pole weld to
  // 16 * 7 ring vertices + 2 poles.
  EXPECT_EQ(pm.positions.size(), 16u * 7u + 2u);
  EXPECT_EQ(pm.faceCount(), sphere.triangleCount());
  EXPECT_EQ(pm.degenerate_removed, 0u);
  EXPECT_EQ(pm.nonmanifold_split, 0u);
  // Closed surface: every face has three neighbours.
  for (std::int32_t n : pm.neighbors) EXPECT_GE(n, 0);
}

TEST(MeshPrep, NonManifoldFaceIsSplitOffAndDegeneratesAreCounted) {
  scene::MeshInstance fin;
  // Three triangles on one edge (0,1): the third makes the edge complex. Then a zero-area
  // triangle and one that welding collapses (vertex 6 is within tolerance of vertex 0).
  fin.positions = {{0, 0, 0}, {1, 0, 0}, {0.5f, 1, 0}, {0.5f, -1, 0}, {0.5f, 0, 1}, {2, 0, 0}, {1e-9f, 0, 0}};
  fin.indices = {0, 1, 2, 1, 0, 3, 0, 1, 4, 0, 1, 5, 0, 6, 2};
  fin.normals.assign(fin.positions.size(), glm::vec3(0, 0, 1));
  const PreparedMesh pm = prepareMesh(fin, 1e-6);
  EXPECT_EQ(pm.faceCount(), 3u);
  EXPECT_EQ(pm.degenerate_removed, 2u);
  EXPECT_EQ(pm.nonmanifold_split, 1u);
  EXPECT_EQ(pm.source_face, (std::vector<std::uint32_t>{0, 1, 2}));

  // The whole pipeline on it: the fin gets its own place in the atlas, no overlaps.
  scene::Scene scene = tm::makeScene({fin});
  UnwrapOptions options;
  options.resolution = 64;
  Expected<UnwrapResult> result = unwrap(scene, options);
  ASSERT_TRUE(result) << result.status().toString();
  EXPECT_EQ(result->report.nonmanifold_split, 1u);
  EXPECT_EQ(result->report.degenerate_removed, 2u);
  EXPECT_EQ(scene.meshes[0].triangleCount(), 3u);
  const testing::OracleResult oracle = testing::checkWithOracle(scene, result->atlas);
  EXPECT_EQ(oracle.chart_overlap_texels + oracle.center_overlaps + oracle.flipped + oracle.gutter_violations, 0u)
      << oracle.first_problem;
}

TEST(Segment, HardEdgesAndConeLimitCharts) {
  const PreparedMesh cube = prepareMesh(tm::cube(1.0f, 3), 1e-6);
  EXPECT_EQ(segmentCharts(cube, {}).chart_count, 6u);
  const PreparedMesh plane = prepareMesh(tm::planeWithHoles(1.0f, 12), 1e-6);
  EXPECT_EQ(segmentCharts(plane, {}).chart_count, 1u);
  // A sphere needs at least the 4 pi / (cone solid angle) charts: with a 30 degree cone
  // a cap covers 1 - cos 30 of the hemisphere's 2 pi... so more than 7 charts.
  const PreparedMesh sphere = prepareMesh(tm::sphere(1.0f, 32, 16), 1e-6);
  SegmentOptions narrow;
  narrow.normal_cone_deg = 30.0;
  const Segmentation seg = segmentCharts(sphere, narrow);
  EXPECT_GT(seg.chart_count, 7u);
  // Every face's normal within the cone of its chart's mean normal (smoothing included).
  std::vector<glm::dvec3> sum(seg.chart_count, glm::dvec3(0.0));
  for (std::size_t f = 0; f < sphere.faceCount(); ++f) sum[seg.face_chart[f]] += sphere.face_normals[f] * sphere.face_areas[f];
  for (std::size_t f = 0; f < sphere.faceCount(); ++f)
    EXPECT_GT(glm::dot(sphere.face_normals[f], glm::normalize(sum[seg.face_chart[f]])), std::cos(40.0 * M_PI / 180.0));
}

TEST(Flatten, LscmOnAHemisphereCapIsConformalAndUnflipped) {
  const PreparedMesh sphere = prepareMesh(tm::sphere(1.0f, 48, 24), 1e-6);
  // The cap within 45 degrees of the north pole (+Y).
  std::vector<std::uint32_t> cap;
  for (std::uint32_t f = 0; f < sphere.faceCount(); ++f) {
    const glm::dvec3 c = (sphere.positions[sphere.corners[3 * f]] + sphere.positions[sphere.corners[3 * f + 1]] +
                          sphere.positions[sphere.corners[3 * f + 2]]) / 3.0;
    if (c.y / glm::length(c) > std::cos(M_PI / 4)) cap.push_back(f);
  }
  std::vector<Chart> out;
  FlattenStats stats;
  flattenChart(sphere, cap, 0, {}, out, stats);
  ASSERT_EQ(out.size(), 1u);
  EXPECT_EQ(stats.lscm, 1u);
  EXPECT_EQ(stats.splits, 0u);
  const Chart& c = out[0];
  double max_angle = 1.0, max_stretch = 1.0;
  for (std::size_t fi = 0; fi < c.faces.size(); ++fi) {
    const std::uint32_t f = c.faces[fi];
    const TriangleDistortion d = triangleDistortion(
        sphere.positions[sphere.corners[3 * f]], sphere.positions[sphere.corners[3 * f + 1]],
        sphere.positions[sphere.corners[3 * f + 2]], c.uv[c.local_corners[3 * fi]], c.uv[c.local_corners[3 * fi + 1]],
        c.uv[c.local_corners[3 * fi + 2]], 1.0);
    ASSERT_GT(d.signed_area_ratio, 0.0);
    max_angle = std::max(max_angle, d.angle_distortion);
    max_stretch = std::max(max_stretch, d.area_stretch);
  }
  EXPECT_LT(max_angle, 1.1);  // conformal up to the discretisation
  // Conformal maps of a 45-degree cap: scale ratio centre/rim ~ sec^2(22.5) ~ 1.17 in area.
  EXPECT_LT(max_stretch, 1.25);
  EXPECT_FALSE(chartSelfOverlaps(c));
}

TEST(Flatten, OverlongStripIsSplitUntilStretchIsBounded) {
  // A half torus tube flattened in one piece stretches; a tight limit forces splits.
  const PreparedMesh torus = prepareMesh(tm::torus(1.0f, 0.4f, 32, 16), 1e-6);
  std::vector<std::uint32_t> all(torus.faceCount());
  std::iota(all.begin(), all.end(), 0u);
  std::vector<Chart> out;
  FlattenStats stats;
  FlattenOptions tight;
  tight.max_area_stretch = 1.2;
  flattenChart(torus, all, 0, tight, out, stats);  // closed surface: no border to pin
  EXPECT_GT(stats.splits, 0u);
  EXPECT_GT(out.size(), 1u);
  std::size_t faces = 0;
  for (const Chart& c : out) faces += c.faces.size();
  EXPECT_EQ(faces, torus.faceCount());
}

TEST(Distortion, KnownJacobians) {
  const glm::dvec3 p0(0, 0, 0), p1(1, 0, 0), p2(0, 1, 0);
  // Identity, uniform scale 2 (area 4 vs chart ratio 4 -> no stretch), anisotropic 2x1, mirror.
  TriangleDistortion d = triangleDistortion(p0, p1, p2, {0, 0}, {1, 0}, {0, 1}, 1.0);
  EXPECT_NEAR(d.area_stretch, 1.0, 1e-12);
  EXPECT_NEAR(d.angle_distortion, 1.0, 1e-12);
  d = triangleDistortion(p0, p1, p2, {0, 0}, {2, 0}, {0, 2}, 4.0);
  EXPECT_NEAR(d.area_stretch, 1.0, 1e-12);
  d = triangleDistortion(p0, p1, p2, {0, 0}, {2, 0}, {0, 1}, 1.0);
  EXPECT_NEAR(d.area_stretch, 2.0, 1e-12);
  EXPECT_NEAR(d.angle_distortion, 2.0, 1e-12);
  d = triangleDistortion(p0, p1, p2, {0, 0}, {0, 1}, {1, 0}, 1.0);
  EXPECT_LT(d.signed_area_ratio, 0.0);
  EXPECT_TRUE(std::isinf(d.area_stretch));
}

TEST(Pack, AnyResolutionAndWideGutter) {
  scene::Scene scene = tm::makeScene({tm::torus(1.0f, 0.3f, 48, 16)});
  UnwrapOptions options;
  options.resolution = 300;  // not a power of two: any size works
  options.gutter_texels = 3;
  Expected<UnwrapResult> a = unwrap(scene, options);
  ASSERT_TRUE(a) << a.status().toString();
  EXPECT_EQ(a->report.resolution, 300);
  const testing::OracleResult oracle = testing::checkWithOracle(scene, a->atlas);
  EXPECT_EQ(oracle.chart_overlap_texels + oracle.gutter_violations, 0u) << oracle.first_problem;
}

}  // namespace
}  // namespace lightlink::charts
