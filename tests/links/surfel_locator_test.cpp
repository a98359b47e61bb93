// SurfelLocator: the pruned per-fine-cell candidate lists of big triangles must give the owner
// the definition gives (nearest of the 3 x 3 cells' candidates, first of equals), for every
// hit. ownerOfHitExhaustive() is that definition; these tests trace real rays (and place
// points by hand on cell corners and edges, where pruning is tightest) and compare.
#include "core/links/surfel_locator.h"

#include <cstdint>
#include <random>

#include <gtest/gtest.h>

#include "core/rt/accel.h"
#include "core/scene/load.h"
#include "core/surfels/surfels.h"
#include "tests/common/scene_builders.h"
#include "tests/common/testing.h"

namespace lightlink::links {
namespace {

using lightlink::testing::addBox;
using lightlink::testing::addQuad;

struct Counts {
  std::size_t compared = 0, mismatched = 0;
};

// Rays from random points inside `box` in random directions; every front or back hit is
// looked up both ways.
Counts compareOnTracedHits(const scene::Scene& scene, const SurfelLocator& locator, const Aabb& box, int rays,
                           std::uint32_t seed) {
  auto accel = rt::Accel::build(scene);
  EXPECT_TRUE(accel) << accel.status().toString();
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u01(0.0f, 1.0f);
  Counts counts;
  for (int i = 0; i < rays; ++i) {
    const glm::vec3 o = box.min + glm::vec3(u01(rng), u01(rng), u01(rng)) * box.extent();
    glm::vec3 d(u01(rng) - 0.5f, u01(rng) - 0.5f, u01(rng) - 0.5f);
    if (glm::dot(d, d) < 1e-6f) continue;
    const rt::Hit h = accel->intersect(rt::Ray{o, 0.0f, d, std::numeric_limits<float>::infinity()});
    if (!h.hit()) continue;
    const glm::vec3 p = o + h.t * d;
    const glm::vec3 n = h.backFacing(d) ? -h.ng : h.ng;
    const std::uint32_t fast = locator.ownerOfHit(h.mesh, h.triangle, h.u, h.v, p, n);
    const std::uint32_t exact = locator.ownerOfHitExhaustive(h.mesh, h.triangle, h.u, h.v, p, n);
    ++counts.compared;
    if (fast != exact) {
      if (++counts.mismatched <= 10)
        ADD_FAILURE() << "mesh " << h.mesh << " triangle " << h.triangle << " (u, v) = (" << h.u << ", " << h.v
                    << "): pruned owner " << fast << ", exhaustive " << exact;
    }
  }
  return counts;
}

// Points at fine-cell corners, edge midpoints and on a dense lattice of every triangle (in
// (u, v) and a hair off the plane), where a wrongly pruned candidate would show first.
Counts compareOnLattice(const scene::Scene& scene, const SurfelLocator& locator, int per_side) {
  Counts counts;
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> jitter(-1e-6f, 1e-6f);
  for (std::uint32_t m = 0; m < scene.meshes.size(); ++m) {
    const scene::MeshInstance& mesh = scene.meshes[m];
    for (std::uint32_t t = 0; t < mesh.triangleCount(); ++t) {
      const glm::vec3 p0 = mesh.positions[mesh.indices[3 * t]], p1 = mesh.positions[mesh.indices[3 * t + 1]],
                      p2 = mesh.positions[mesh.indices[3 * t + 2]];
      const glm::vec3 n = glm::cross(p1 - p0, p2 - p0);
      for (int a = 0; a <= per_side; ++a) {
        for (int b = 0; a + b <= per_side; ++b) {
          const float u = float(a) / float(per_side), v = float(b) / float(per_side);
          const glm::vec3 p = (1.0f - u - v) * p0 + u * p1 + v * p2 + jitter(rng) * glm::normalize(n);
          const std::uint32_t fast = locator.ownerOfHit(m, t, u, v, p, n);
          const std::uint32_t exact = locator.ownerOfHitExhaustive(m, t, u, v, p, n);
          ++counts.compared;
          if (fast != exact) {
            if (++counts.mismatched <= 10)
              ADD_FAILURE() << "mesh " << m << " triangle " << t << " (u, v) = (" << u << ", " << v << "): pruned owner "
                          << fast << ", exhaustive " << exact;
          }
        }
      }
    }
  }
  return counts;
}

// The pruned lookup against the exhaustive scan on `rays` hits traced from `seed`: no owner
// may differ, and at least `min_compared` hits must land on a surface to compare.
void expectExhaustiveOwnersOnTracedHits(const scene::Scene& s, const SurfelLocator& locator, int rays,
                                        std::uint32_t seed, std::size_t min_compared) {
  const Counts traced = compareOnTracedHits(s, locator, s.bounds, rays, seed);
  EXPECT_GT(traced.compared, min_compared);
  EXPECT_EQ(traced.mismatched, 0u);
}

TEST(SurfelLocator, PrunedListsGiveTheExhaustiveOwnerInABoxRoom) {
  scene::Scene s;
  addBox(s, {0, 0, 0}, {4, 3, 5}, /*inward=*/true);
  addBox(s, {1, 0, 1}, {2, 1.3f, 2.2f}, /*inward=*/false);
  lightlink::testing::finishScene(s);
  // 8192 surfels on 24 triangles: every triangle is "big" (hundreds of surfels each).
  auto placed = surfels::placeSurfels(s, {.count = 8192});
  ASSERT_TRUE(placed) << placed.status().toString();
  const SurfelLocator locator(*placed, s);
  expectExhaustiveOwnersOnTracedHits(s, locator, 200000, 1, 150000);
  // (u, v) on multiples of 1/360 hit every fine-cell corner of triangles with g up to 45.
  const Counts lattice = compareOnLattice(s, locator, 360);
  EXPECT_GT(lattice.compared, 1000000u);
  EXPECT_EQ(lattice.mismatched, 0u);
}

TEST(SurfelLocator, PrunedListsGiveTheExhaustiveOwnerFarFromTheOrigin) {
  // A 2 m room 10 km away: float spacing of the coordinates (~1 mm) is no longer small
  // against a fine cell (~3 cm), the case the lists' margins are there for.
  scene::Scene s;
  const glm::vec3 far(1.0e4f, -2.0e3f, 5.0e3f);
  addBox(s, far, far + glm::vec3(2.0f, 2.0f, 2.0f), /*inward=*/true);
  lightlink::testing::finishScene(s);
  auto placed = surfels::placeSurfels(s, {.count = 4096});
  ASSERT_TRUE(placed) << placed.status().toString();
  const SurfelLocator locator(*placed, s);
  expectExhaustiveOwnersOnTracedHits(s, locator, 100000, 2, 90000);
  EXPECT_EQ(compareOnLattice(s, locator, 200).mismatched, 0u);
}

TEST(SurfelLocator, PrunedListsGiveTheExhaustiveOwnerInTheDemoScene) {
  auto loaded = scene::loadGltf((lightlink::testing::sourceDir() / "clients/demo/cornell_box.gltf").string());
  ASSERT_TRUE(loaded) << loaded.status().toString();
  // The "medium" preset's surfel count: the configuration the benchmark times.
  auto placed = surfels::placeSurfels(*loaded, {.count = 32768});
  ASSERT_TRUE(placed) << placed.status().toString();
  const SurfelLocator locator(*placed, *loaded);
  // The lists are in use and short (~8 here; the exhaustive scan sees ~20 candidates).
  EXPECT_GT(locator.fineListCount(), 10000u);
  EXPECT_LT(locator.meanFineListLength(), 12.0);
  expectExhaustiveOwnersOnTracedHits(*loaded, locator, 300000, 3, 200000);
}

}  // namespace
}  // namespace lightlink::links
