// SurfelLocator: a big triangle answers from its owner raster, whose cells hold the surfel
// nearest to the cell's centre among the 3 x 3 cells' candidates. These tests check that
// definition exactly (the raster at every cell centre equals the scan it samples), its bound
// on traced hits (the raster owner is never farther from the hit than the nearest candidate
// plus one raster cell diagonal) and how rarely it differs from the nearest at all, also far
// from the origin where the float spacing of coordinates is coarse.
#include "core/links/surfel_locator.h"

#include <cstdint>
#include <cstdio>
#include <random>

#include <gtest/gtest.h>

#include "core/rt/accel.h"
#include "core/scene/load.h"
#include "core/scene/subdivide.h"
#include "core/surfels/surfels.h"
#include "tests/common/scene_builders.h"
#include "tests/common/testing.h"

namespace lightlink::links {
namespace {

using lightlink::testing::addBox;

// Every raster cell centre of every big triangle: the raster's owner must be the scan's.
// Returns the cells compared.
std::size_t expectRasterIsTheScanAtCellCentres(const scene::Scene& scene, const SurfelLocator& locator) {
  std::size_t compared = 0, mismatched = 0;
  for (std::uint32_t m = 0; m < scene.meshes.size(); ++m) {
    const scene::MeshInstance& mesh = scene.meshes[m];
    for (std::uint32_t t = 0; t < mesh.triangleCount(); ++t) {
      const std::uint32_t size = locator.rasterSize(m, t);
      if (size == 0) continue;
      const glm::vec3 p0 = mesh.positions[mesh.indices[3 * t]], p1 = mesh.positions[mesh.indices[3 * t + 1]],
                      p2 = mesh.positions[mesh.indices[3 * t + 2]];
      const glm::vec3 e1 = p1 - p0, e2 = p2 - p0, n = glm::cross(e1, e2);
      const float inv = 1.0f / static_cast<float>(size);
      for (std::uint32_t fv = 0; fv < size; ++fv) {
        for (std::uint32_t fu = 0; fu < size; ++fu) {
          // Cells wholly beyond the hypotenuse hold no owner (no hit lands there).
          if (static_cast<double>(fu + fv) / static_cast<double>(size) > 1.0 + 1e-4) continue;
          const float u = (static_cast<float>(fu) + 0.5f) * inv, v = (static_cast<float>(fv) + 0.5f) * inv;
          const glm::vec3 c = p0 + u * e1 + v * e2;
          const std::uint32_t raster = locator.ownerOfHit(m, t, u, v, c, n);
          const std::uint32_t scan = locator.ownerOfHitNearest(m, t, u, v, c, n);
          ++compared;
          if (raster != scan && ++mismatched <= 10)
            ADD_FAILURE() << "mesh " << m << " triangle " << t << " cell (" << fu << ", " << fv << "): raster "
                          << raster << ", scan " << scan;
        }
      }
    }
  }
  EXPECT_EQ(mismatched, 0u);
  return compared;
}

// The surfel lying on (mesh, triangle) when exactly one does, else kNoSurfel.
std::uint32_t onlySurfelOn(const surfels::Surfels& surfels, std::uint32_t mesh, std::uint32_t triangle) {
  std::uint32_t found = kNoSurfel, count = 0;
  for (std::uint32_t i = 0; i < surfels.size(); ++i) {
    if (surfels.mesh[i] != mesh || surfels.triangle[i] != triangle) continue;
    found = i;
    ++count;
  }
  return count == 1 ? found : kNoSurfel;
}

struct Traced {
  std::size_t on_rasters = 0;  // hits on big triangles
  std::size_t same = 0;        // of those, raster owner == nearest candidate
  std::size_t small = 0;       // hits on triangles of one surfel or none (1 x 1 rasters)
};

// Rays from random points inside the scene bounds in random directions. On a big triangle
// the raster owner may not be farther from the hit than the nearest candidate plus one
// raster cell diagonal (plus float slack relative to the coordinates); elsewhere both
// lookups are the same code and must agree.
Traced expectRasterBoundOnTracedHits(const scene::Scene& scene, const surfels::Surfels& surfels,
                                     const SurfelLocator& locator, int rays, std::uint32_t seed) {
  auto accel = rt::Accel::build(scene);
  EXPECT_TRUE(accel) << accel.status().toString();
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u01(0.0f, 1.0f);
  const Aabb& box = scene.bounds;
  const float slack = 1e-5f * glm::length(glm::max(glm::abs(box.min), glm::abs(box.max)));
  Traced traced;
  std::size_t failures = 0;
  for (int i = 0; i < rays; ++i) {
    const glm::vec3 o = box.min + glm::vec3(u01(rng), u01(rng), u01(rng)) * box.extent();
    glm::vec3 d(u01(rng) - 0.5f, u01(rng) - 0.5f, u01(rng) - 0.5f);
    if (glm::dot(d, d) < 1e-6f) continue;
    const rt::Hit h = accel->intersect(rt::Ray{o, 0.0f, d, std::numeric_limits<float>::infinity()});
    if (!h.hit()) continue;
    const glm::vec3 p = o + h.t * d;
    const glm::vec3 n = h.backFacing(d) ? -h.ng : h.ng;
    const std::uint32_t owner = locator.ownerOfHit(h.mesh, h.triangle, h.u, h.v, p, n);
    const std::uint32_t nearest = locator.ownerOfHitNearest(h.mesh, h.triangle, h.u, h.v, p, n);
    const float diagonal = locator.rasterCellDiagonal(h.mesh, h.triangle);
    if ((owner >= surfels.size() || nearest >= surfels.size()) && ++failures <= 10) {
      ADD_FAILURE() << "no owner for a hit on mesh " << h.mesh << " triangle " << h.triangle;
      continue;
    }
    if (diagonal == 0.0f) {
      // A small triangle: the surfel lying on it, when one does (the surfel nearest its
      // centroid otherwise, which SmallTrianglesAnswerFromTheirOneCellRasters checks).
      ++traced.small;
      const std::uint32_t own = onlySurfelOn(surfels, h.mesh, h.triangle);
      if (own != kNoSurfel && owner != own && ++failures <= 10)
        ADD_FAILURE() << "small triangle: owner " << owner << ", its surfel " << own;
      continue;
    }
    ++traced.on_rasters;
    traced.same += owner == nearest ? 1 : 0;
    const float d_owner = glm::length(surfels.position[owner] - p);
    const float d_nearest = glm::length(surfels.position[nearest] - p);
    if (d_owner > d_nearest + diagonal + slack && ++failures <= 10)
      ADD_FAILURE() << "mesh " << h.mesh << " triangle " << h.triangle << " (u, v) = (" << h.u << ", " << h.v
                    << "): raster owner " << d_owner << " m away, nearest " << d_nearest << " m, cell diagonal "
                    << diagonal;
  }
  EXPECT_EQ(failures, 0u);
  // How often the raster gives the nearest itself (docs/precompute.md "Owner lookup").
  if (traced.on_rasters > 0)
    std::printf("raster owner == nearest candidate on %.1f %% of %zu hits on big triangles\n",
                100.0 * double(traced.same) / double(traced.on_rasters), traced.on_rasters);
  return traced;
}

TEST(SurfelLocator, RasterHoldsTheNearestCandidateInABoxRoom) {
  scene::Scene s;
  addBox(s, {0, 0, 0}, {4, 3, 5}, /*inward=*/true);
  addBox(s, {1, 0, 1}, {2, 1.3f, 2.2f}, /*inward=*/false);
  lightlink::testing::finishScene(s);
  // 8192 surfels on 24 triangles: every triangle is "big" (hundreds of surfels each).
  auto placed = surfels::placeSurfels(s, {.count = 8192});
  ASSERT_TRUE(placed) << placed.status().toString();
  const SurfelLocator locator(*placed, s);
  EXPECT_EQ(locator.rasterFactor(), SurfelLocator::kRaster);
  EXPECT_GT(expectRasterIsTheScanAtCellCentres(s, locator), 8192u * 16u / 3u);
  const Traced traced = expectRasterBoundOnTracedHits(s, *placed, locator, 200000, 1);
  EXPECT_GT(traced.on_rasters, 150000u);
  // Only a band along the Voronoi edges differs (half a raster cell either side): ~18 % of
  // the hits at r = 4.
  EXPECT_GT(double(traced.same), 0.7 * double(traced.on_rasters));
}

TEST(SurfelLocator, RasterHoldsTheNearestCandidateFarFromTheOrigin) {
  // A 2 m room 10 km away: float spacing of the coordinates (~1 mm) is no longer small
  // against a raster cell (~1 cm).
  scene::Scene s;
  const glm::vec3 far(1.0e4f, -2.0e3f, 5.0e3f);
  addBox(s, far, far + glm::vec3(2.0f, 2.0f, 2.0f), /*inward=*/true);
  lightlink::testing::finishScene(s);
  auto placed = surfels::placeSurfels(s, {.count = 4096});
  ASSERT_TRUE(placed) << placed.status().toString();
  const SurfelLocator locator(*placed, s);
  expectRasterIsTheScanAtCellCentres(s, locator);
  const Traced traced = expectRasterBoundOnTracedHits(s, *placed, locator, 100000, 2);
  EXPECT_GT(traced.on_rasters, 90000u);
  EXPECT_GT(double(traced.same), 0.7 * double(traced.on_rasters));
}

// The bundled demo scene with `count` surfels placed on it.
struct DemoSurfels {
  scene::Scene scene;
  surfels::Surfels surfels;
};
DemoSurfels demoWithSurfels(std::uint32_t count) {
  auto loaded = scene::loadGltf((lightlink::testing::sourceDir() / "clients/demo/cornell_box.gltf").string());
  EXPECT_TRUE(loaded) << loaded.status().toString();
  if (!loaded) return {};
  auto placed = surfels::placeSurfels(*loaded, {.count = count});
  EXPECT_TRUE(placed) << placed.status().toString();
  if (!placed) return {std::move(loaded).value(), {}};
  return {std::move(loaded).value(), std::move(placed).value()};
}

TEST(SurfelLocator, RasterHoldsTheNearestCandidateInTheDemoScene) {
  // The "medium" preset's surfel count: the configuration the benchmark times.
  const DemoSurfels demo = demoWithSurfels(32768);
  ASSERT_GT(demo.surfels.size(), 0u);
  const SurfelLocator locator(demo.surfels, demo.scene);
  EXPECT_GT(locator.rasterCellCount(), 200000u);
  expectRasterIsTheScanAtCellCentres(demo.scene, locator);
  const Traced traced = expectRasterBoundOnTracedHits(demo.scene, demo.surfels, locator, 300000, 3);
  EXPECT_GT(traced.on_rasters, 200000u);
  EXPECT_GT(double(traced.same), 0.7 * double(traced.on_rasters));
}

TEST(SurfelLocator, SixteenBitRasterAnswersAsTheThirtyTwoBitOne) {
  // Under 65,535 surfels the raster is kept in 16 bits; every answer must be the same.
  const DemoSurfels demo = demoWithSurfels(8192);
  ASSERT_GT(demo.surfels.size(), 0u);
  const SurfelLocator narrow(demo.surfels, demo.scene);
  const SurfelLocator wide(demo.surfels, demo.scene, SurfelLocator::kRasterBudget, /*narrow_raster=*/false);
  EXPECT_EQ(narrow.rasterCellBytes(), 2u);
  EXPECT_EQ(wide.rasterCellBytes(), 4u);
  ASSERT_EQ(narrow.rasterCellCount(), wide.rasterCellCount());
  std::size_t empty = 0;
  for (std::uint32_t k = 0; k < narrow.rasterCellCount(); ++k) {
    ASSERT_EQ(narrow.slotOwner(k), wide.slotOwner(k)) << "raster cell " << k;
    empty += wide.slotOwner(k) == kNoSurfel ? 1 : 0;
  }
  // Cells beyond the hypotenuses stay empty: kNoSurfel must survive the narrowing too.
  EXPECT_GT(empty, 0u);
  EXPECT_LT(empty, narrow.rasterCellCount());
}

TEST(SurfelLocator, SmallTrianglesAnswerFromTheirOneCellRasters) {
  // A room split into 6144 triangles with 2048 surfels: most triangles hold one surfel or
  // none (then the surfel nearest their centroid stands for them).
  scene::Scene s;
  addBox(s, {0, 0, 0}, {4, 3, 5}, /*inward=*/true);
  scene::subdivide(s, 4);
  lightlink::testing::finishScene(s);
  auto placed = surfels::placeSurfels(s, {.count = 2048});
  ASSERT_TRUE(placed) << placed.status().toString();
  const SurfelLocator locator(*placed, s);
  const Traced traced = expectRasterBoundOnTracedHits(s, *placed, locator, 100000, 5);
  EXPECT_GT(traced.small, 50000u);
  EXPECT_GT(traced.on_rasters, 1000u);
  // Every hit on a small triangle goes to the surfel on it, or (none on it) to the surfel
  // nearest its centroid, wherever on the triangle it lands.
  std::size_t own = 0, total = 0;
  for (std::uint32_t m = 0; m < s.meshes.size(); ++m) {
    const scene::MeshInstance& mesh = s.meshes[m];
    for (std::uint32_t t = 0; t < mesh.triangleCount(); ++t) {
      if (locator.rasterSize(m, t) != 0) continue;
      const glm::vec3 p0 = mesh.positions[mesh.indices[3 * t]], p1 = mesh.positions[mesh.indices[3 * t + 1]],
                      p2 = mesh.positions[mesh.indices[3 * t + 2]];
      const glm::vec3 n = glm::normalize(glm::cross(p1 - p0, p2 - p0));
      const std::uint32_t on = onlySurfelOn(*placed, m, t);
      const std::uint32_t expected = on != kNoSurfel ? on : locator.owner((p0 + p1 + p2) / 3.0f, n);
      for (const glm::vec2 uv : {glm::vec2(0.3f, 0.3f), glm::vec2(0.9f, 0.05f), glm::vec2(0.0f, 1.0f)}) {
        const std::uint32_t o = locator.ownerOfHit(m, t, uv.x, uv.y, glm::vec3(0.0f), n);
        ASSERT_EQ(o, expected) << "mesh " << m << " triangle " << t;
      }
      ++total;
      own += on != kNoSurfel ? 1 : 0;
    }
  }
  EXPECT_GT(total, 2000u);  // 2945 of the 6144
  EXPECT_GT(own, 1000u);  // the triangles that hold their own surfel
}

// A double-sided sheet over a floor: a hit on the sheet's underside is owned by a surfel of
// the underside (facing down), one on its top by a surfel of the top, on big and on small
// triangles alike; the floor is single-sided and has no back side to own.
TEST(SurfelLocator, EachSideOfADoubleSidedSheetOwnsItsHits) {
  for (const int subdivisions : {0, 3}) {
    scene::Scene s;
    const int plain = lightlink::testing::addMaterial(s, glm::vec3(0.5f));
    const int sheet = lightlink::testing::addMaterial(s, glm::vec3(0.5f), glm::vec3(0.0f), /*double_sided=*/true);
    lightlink::testing::addQuad(s, {-2, 0, 2}, {2, 0, 2}, {2, 0, -2}, {-2, 0, -2}, plain);
    lightlink::testing::addQuad(s, {-1, 0.01f, 1}, {1, 0.01f, 1}, {1, 0.01f, -1}, {-1, 0.01f, -1}, sheet);
    scene::subdivide(s, subdivisions);
    lightlink::testing::finishScene(s);
    auto placed = surfels::placeSurfels(s, {.count = 4096});
    ASSERT_TRUE(placed) << placed.status().toString();
    const SurfelLocator locator(*placed, s);
    const scene::MeshInstance& mesh = s.meshes[1];
    std::size_t checked = 0;
    for (std::uint32_t t = 0; t < mesh.triangleCount(); ++t) {
      for (const glm::vec2 uv : {glm::vec2(0.3f, 0.3f), glm::vec2(0.6f, 0.1f), glm::vec2(0.1f, 0.1f)}) {
        const glm::vec3 p = (1.0f - uv.x - uv.y) * mesh.positions[mesh.indices[3 * t]] +
                            uv.x * mesh.positions[mesh.indices[3 * t + 1]] + uv.y * mesh.positions[mesh.indices[3 * t + 2]];
        for (const bool back : {false, true}) {
          const glm::vec3 n(0.0f, back ? -1.0f : 1.0f, 0.0f);
          const std::uint32_t o = locator.ownerOfHit(locator.sideMesh(1, back), t, uv.x, uv.y, p, n);
          ASSERT_NE(o, kNoSurfel);
          EXPECT_EQ(placed->mesh[o], 1u);
          EXPECT_GT(glm::dot(placed->normal[o], n), 0.99f) << "triangle " << t << (back ? " back" : " front");
          ++checked;
        }
      }
    }
    EXPECT_GT(checked, 0u);
    // The single-sided floor has no back-side tables.
    EXPECT_EQ(locator.rasterSlot(locator.sideMesh(0, true), 0, 0.3f, 0.3f), kNoSurfel);
  }
}

TEST(SurfelLocator, RasterShrinksToItsMemoryBudget) {
  scene::Scene s;
  addBox(s, {0, 0, 0}, {1, 1, 1}, /*inward=*/true);
  lightlink::testing::finishScene(s);
  auto placed = surfels::placeSurfels(s, {.count = 2048});
  ASSERT_TRUE(placed) << placed.status().toString();
  const SurfelLocator full(*placed, s);
  ASSERT_EQ(full.rasterFactor(), 4u);
  // A budget below the 4 x 4 raster but above 2 x 2 gives r = 2 (a quarter of the cells);
  // below even 1 x 1 it stays at r = 1. The definition and its bound hold either way.
  const SurfelLocator half(*placed, s, full.rasterCellCount() / 2);
  EXPECT_EQ(half.rasterFactor(), 2u);
  EXPECT_EQ(half.rasterCellCount() * 4, full.rasterCellCount());
  const SurfelLocator one(*placed, s, 1);
  EXPECT_EQ(one.rasterFactor(), 1u);
  for (const SurfelLocator* locator : {&half, &one}) {
    expectRasterIsTheScanAtCellCentres(s, *locator);
    expectRasterBoundOnTracedHits(s, *placed, *locator, 20000, 4);
  }
}

}  // namespace
}  // namespace lightlink::links
