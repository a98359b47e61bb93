// Tests for FlatBvh: its occlusion answers against Embree's (Accel::occluded) on random rays
// and on surface-to-surface shadow rays of the bundled Cornell box, the same arrays at any
// thread count, and what it leaves out (dynamic meshes, meshes that cast no shadow).
#include "core/rt/flat_bvh.h"

#include <cstring>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <tbb/task_arena.h>

#include "core/scene/load.h"
#include "tests/common/testing.h"

namespace lightlink::rt {
namespace {

using glm::vec3;

// `n` random triangles of edge up to `size` in the cube [0, 1]^3: a tangle with many
// overlaps, so rays cross and graze plenty of them.
scene::Scene randomTriangles(int n, float size, std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(0.0f, 1.0f), e(-size, size);
  scene::MeshInstance mesh;
  mesh.name = "tangle";
  for (int i = 0; i < n; ++i) {
    const vec3 a(u(rng), u(rng), u(rng));
    mesh.positions.push_back(a);
    mesh.positions.push_back(a + vec3(e(rng), e(rng), e(rng)));
    mesh.positions.push_back(a + vec3(e(rng), e(rng), e(rng)));
    for (int k = 0; k < 3; ++k) mesh.indices.push_back(std::uint32_t(3 * i + k));
  }
  mesh.normals.assign(mesh.positions.size(), vec3(0, 0, 1));
  scene::Scene s;
  s.meshes.push_back(std::move(mesh));
  return s;
}

FlatBvh buildOrDie(const scene::Scene& s) {
  auto bvh = FlatBvh::build(s);
  EXPECT_TRUE(bvh) << bvh.status().toString();
  if (!bvh) std::abort();
  return std::move(*bvh);
}

TEST(FlatBvh, AgreesWithEmbreeOnRandomRays) {
  const scene::Scene s = randomTriangles(3000, 0.08f, 7);
  const FlatBvh bvh = buildOrDie(s);
  auto accel = Accel::build(s);
  ASSERT_TRUE(accel) << accel.status().toString();
  EXPECT_EQ(bvh.triangles.size(), 3000u);
  EXPECT_LE(bvh.depth, kBvhMaxDepth);
  std::mt19937 rng(11);
  std::uniform_real_distribution<float> u(-0.2f, 1.2f), len(0.01f, 1.5f);
  int blocked = 0, differ = 0;
  const int rays = 40000;
  for (int i = 0; i < rays; ++i) {
    Ray r;
    r.origin = vec3(u(rng), u(rng), u(rng));
    r.dir = glm::normalize(vec3(u(rng) - 0.5f, u(rng) - 0.5f, u(rng) - 0.5f)) * len(rng);
    r.tnear = i % 3 == 0 ? 0.1f : 0.0f;
    r.tfar = i % 2 == 0 ? 1.0f : 0.7f;
    const bool mine = bvh.occluded(r), embree = accel->occluded(r);
    blocked += embree;
    differ += mine != embree;
  }
  // Both tests are watertight; a disagreement needs a hit within a few ulps of tnear/tfar.
  EXPECT_GT(blocked, rays / 10);
  EXPECT_LT(blocked, rays * 9 / 10);
  EXPECT_EQ(differ, 0) << "of " << rays << " rays, " << blocked << " blocked";
}

TEST(FlatBvh, AgreesWithEmbreeOnShadowRaysBetweenCornellBoxSurfaces) {
  auto s = scene::loadGltf((testing::sourceDir() / "clients/demo/cornell_box.gltf").string());
  ASSERT_TRUE(s) << s.status().toString();
  const FlatBvh bvh = buildOrDie(*s);
  auto accel = Accel::build(*s);
  ASSERT_TRUE(accel) << accel.status().toString();
  // Points on random static triangles (area-uniform enough for a test), joined as the
  // emitter sampler joins a receiver and an emitter sample: offset origin, stop short by eps.
  struct Point {
    vec3 p, n;
  };
  std::vector<Point> points;
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  for (const auto& mesh : s->meshes) {
    if (!mesh.is_static) continue;
    for (std::uint32_t t = 0; t < mesh.triangleCount(); ++t)
      for (int k = 0; k < 8; ++k) {
        const vec3 a = mesh.positions[mesh.indices[3 * t]], b = mesh.positions[mesh.indices[3 * t + 1]],
                   c = mesh.positions[mesh.indices[3 * t + 2]];
        float x = u(rng), y = u(rng);
        if (x + y > 1.0f) x = 1.0f - x, y = 1.0f - y;
        points.push_back({a + x * (b - a) + y * (c - a), glm::cross(b - a, c - a)});
      }
  }
  ASSERT_GT(points.size(), 100u);
  int rays = 0, blocked = 0, differ = 0;
  std::uniform_int_distribution<std::size_t> pick(0, points.size() - 1);
  for (int i = 0; i < 40000; ++i) {
    const Point& x = points[pick(rng)];
    const Point& q = points[pick(rng)];
    const vec3 w = q.p - x.p;
    if (glm::dot(w, w) == 0.0f) continue;
    // As the sampler: the sample lies in front of the receiver and not edge-on to it.
    const float cos_r = glm::dot(x.n, w) / (glm::length(x.n) * glm::length(w));
    const float cos_e = glm::dot(q.n, w) / (glm::length(q.n) * glm::length(w));
    if (!(cos_r > 1e-3f) || !(std::abs(cos_e) > 1e-3f)) continue;
    Ray r;
    r.origin = accel->offsetOrigin(x.p, x.n, w);
    r.dir = q.p - r.origin;
    r.tfar = std::max(0.0f, 1.0f - accel->rayEpsilon() / std::max(glm::length(r.dir), 1e-30f));
    const bool mine = bvh.occluded(r), embree = accel->occluded(r);
    ++rays;
    blocked += embree;
    differ += mine != embree;
    if (mine != embree && differ < 6)
      std::printf("differ: mine %d embree %d cos_r %g cos_e %g len %g\n", mine, embree, cos_r, cos_e, glm::length(w));
  }
  EXPECT_GT(blocked, rays / 20);
  // Edge-on rays (cosine <= 1e-3 at either end) are left out: there a hit within rounding of the
  // ray's own plane goes either way in both tests, and the sampler never traces them.
  EXPECT_EQ(differ, 0) << differ << " of " << rays << " rays differ, " << blocked << " blocked";
  std::printf("Cornell box surface-to-surface rays: %d, blocked %d, differ from Embree %d\n", rays, blocked, differ);
}

TEST(FlatBvh, SameArraysForAnyThreadCount) {
  const scene::Scene s = randomTriangles(20000, 0.05f, 5);
  FlatBvh one, many;
  tbb::task_arena(1).execute([&] { one = buildOrDie(s); });
  tbb::task_arena(4).execute([&] { many = buildOrDie(s); });
  ASSERT_EQ(one.nodes.size(), many.nodes.size());
  ASSERT_EQ(one.triangles.size(), many.triangles.size());
  EXPECT_EQ(std::memcmp(one.nodes.data(), many.nodes.data(), one.nodes.size() * sizeof(BvhNode)), 0);
  EXPECT_EQ(std::memcmp(one.triangles.data(), many.triangles.data(), one.triangles.size() * sizeof(BvhTriangle)), 0);
}

TEST(FlatBvh, LeavesOutDynamicAndShadowlessMeshesAndCountsCutouts) {
  scene::Scene s = randomTriangles(10, 0.1f, 1);
  scene::Scene extra = randomTriangles(5, 0.1f, 2);
  extra.meshes[0].is_static = false;
  s.meshes.push_back(extra.meshes[0]);
  extra.meshes[0].is_static = true, extra.meshes[0].cast_shadows = false;
  s.meshes.push_back(extra.meshes[0]);
  scene::Material cut;
  cut.alpha_mode = scene::Material::AlphaMode::kMask;
  s.materials.push_back(cut);
  s.meshes[0].material = 0;
  const FlatBvh bvh = buildOrDie(s);
  EXPECT_EQ(bvh.triangles.size(), 10u);
  EXPECT_EQ(bvh.cutout_meshes, 1u);
}

TEST(FlatBvh, RejectsBadInputNamingTheMesh) {
  scene::Scene s = randomTriangles(2, 0.1f, 1);
  s.meshes[0].indices[4] = 99;
  auto bad = FlatBvh::build(s);
  ASSERT_FALSE(bad);
  EXPECT_NE(bad.status().toString().find("tangle"), std::string::npos) << bad.status().toString();
  scene::Scene none;
  EXPECT_FALSE(FlatBvh::build(none));
}

}  // namespace
}  // namespace lightlink::rt
