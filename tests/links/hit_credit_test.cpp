// Hit credit: every kernel this CPU can run (the scalar one always, the AVX-512 one where the
// CPU has it) against the definition taken ray by ray (escaped, blocked by a single-sided
// back face, else SurfelLocator::ownerOfHit), bit for bit, on fans traced in a scene with
// every kind of ray (escaped, blocked, a double-sided back face credited, hits on big and on
// small triangles, stray hits that need the locator's full lookup), for ray counts that are
// and are not multiples of 16, over both raster widths.
#include "core/links/hit_credit.h"

#include <cstring>
#include <vector>

#include <gtest/gtest.h>

#include "core/common/sampling.h"
#include "core/links/links.h"
#include "core/links/surfel_locator.h"
#include "core/surfels/surfels.h"
#include "tests/common/scene_builders.h"

namespace lightlink::links {
namespace {

using lightlink::testing::addMaterial;
using lightlink::testing::addQuad;

// A room without a ceiling and without one wall (rays escape), a single-sided panel inside
// (its back blocks rays), a double-sided panel (its back is credited), and one wall split
// into 8 x 8 small quads (triangles with one surfel or none).
// The z = 0 wall in tiles x tiles quads, one mesh each: 8 gives 69 meshes, 2 gives 9 (the
// AVX-512 kernel keeps up to 16 meshes' first triangles in a register, more it gathers).
scene::Scene mixedRoom(int tiles) {
  scene::Scene s;
  const int one_sided = addMaterial(s, glm::vec3(0.5f));
  const int two_sided = addMaterial(s, glm::vec3(0.5f), glm::vec3(0.0f), /*double_sided=*/true);
  const float w = 4.0f;
  addQuad(s, {0, 0, 0}, {w, 0, 0}, {w, 0, w}, {0, 0, w}, one_sided);  // floor, facing +y
  addQuad(s, {0, 0, 0}, {0, 0, w}, {0, w, w}, {0, w, 0}, one_sided);  // x = 0 wall, facing +x
  addQuad(s, {w, 0, 0}, {w, w, 0}, {w, w, w}, {w, 0, w}, one_sided);  // x = w wall, facing -x
  for (int i = 0; i < tiles; ++i) {  // z = 0 wall, facing +z, in small quads
    for (int j = 0; j < tiles; ++j) {
      const float x0 = w * float(i) / float(tiles), x1 = w * float(i + 1) / float(tiles);
      const float y0 = w * float(j) / float(tiles), y1 = w * float(j + 1) / float(tiles);
      addQuad(s, {x0, y0, 0}, {x1, y0, 0}, {x1, y1, 0}, {x0, y1, 0}, one_sided);
    }
  }
  addQuad(s, {1.5f, 0.5f, 1.0f}, {1.5f, 0.5f, 3.0f}, {1.5f, 2.5f, 3.0f}, {1.5f, 2.5f, 1.0f}, one_sided);
  addQuad(s, {2.5f, 0.5f, 1.0f}, {2.5f, 2.5f, 1.0f}, {2.5f, 2.5f, 3.0f}, {2.5f, 0.5f, 3.0f}, two_sided);
  lightlink::testing::finishScene(s);
  return s;
}

struct Outcome {
  HitCredit credit;
  std::vector<Sample> samples;
  std::vector<float> escaped;
};

// What creditHits must give, one ray at a time.
Outcome creditedRayByRay(const rt::RayFan& fan, const rt::HitArrays& hits, const std::vector<std::uint32_t>& double_sided,
                         const SurfelLocator& locator) {
  Outcome o;
  o.escaped.assign(fan.count, 0.0f);
  for (std::uint32_t i = 0; i < fan.count; ++i) {
    if (hits.mesh[i] == rt::kNoHit) {
      o.escaped[i] = 1.0f;
      ++o.credit.escaped;
      continue;
    }
    const glm::vec3 dir(fan.dir_x[i], fan.dir_y[i], fan.dir_z[i]);
    const glm::vec3 ng(hits.ng_x[i], hits.ng_y[i], hits.ng_z[i]);
    const bool back = rt::backFacing(ng, dir);
    if (back && double_sided[hits.mesh[i]] == 0) {
      ++o.credit.back_hits;
      continue;
    }
    const std::uint32_t owner = locator.ownerOfHit(locator.sideMesh(hits.mesh[i], back), hits.triangle[i], hits.u[i], hits.v[i],
                                                   fan.origin + hits.t[i] * dir, back ? -ng : ng);
    if (owner == kNoSurfel) {
      ++o.credit.unowned;
      continue;
    }
    o.samples.push_back(makeSample(owner, i));
  }
  o.credit.sampled = static_cast<std::uint32_t>(o.samples.size());
  return o;
}

void expectEveryKernelCreditsAsTheLocator(int tiles) {
  std::vector<HitCreditKernel> kernels{HitCreditKernel::kScalar};
  const bool avx512 = hitCreditKernelRun(HitCreditKernel::kAvx512) == HitCreditKernel::kAvx512;
  if (avx512) kernels.push_back(HitCreditKernel::kAvx512);
  ::testing::Test::RecordProperty("avx512_kernel_compared", avx512 ? "yes" : "no (not on this CPU)");
  const scene::Scene scene = mixedRoom(tiles);
  auto accel = rt::Accel::build(scene);
  ASSERT_TRUE(accel) << accel.status().toString();
  auto placed = surfels::placeSurfels(scene, {.count = 4096});
  ASSERT_TRUE(placed) << placed.status().toString();
  const std::vector<std::uint32_t> double_sided = doubleSidedByMesh(scene);

  HitCredit kinds;  // over all fans, to show the test saw every kind of ray
  std::size_t stray = 0, fans = 0;
  // The two raster widths, and rasters of one cell per big-triangle cell (a budget too small
  // for more).
  struct Config {
    bool narrow;
    std::size_t budget;
  };
  for (const Config config : {Config{true, SurfelLocator::kRasterBudget}, Config{false, SurfelLocator::kRasterBudget},
                              Config{true, 1}}) {
    const bool narrow = config.narrow;
    const SurfelLocator locator(*placed, scene, config.budget, narrow);
    ASSERT_EQ(locator.rasterCellBytes(), narrow ? 2u : 4u);
    for (int rays : {1024, 1000, 9}) {
      const LinkRays pattern({.rays = rays});
      const std::uint32_t count = pattern.count();
      std::vector<float> dx(count), dy(count), dz(count);
      std::vector<std::uint32_t> mesh(count), triangle(count), slots(count);
      std::vector<float> u(count), v(count), t(count), nx(count), ny(count), nz(count);
      const rt::HitArrays hits{mesh.data(), triangle.data(), u.data(), v.data(), t.data(), nx.data(), ny.data(), nz.data()};
      for (std::uint32_t cache = 0; cache < 60; ++cache) {
        // Lightmap-like caches on the floor and the panels' sides, and sphere caches in the air.
        std::uint64_t state = mixBits(cache * 7919u + static_cast<std::uint64_t>(rays));
        auto uniform = [&] { return unitFloat(state = mixBits(state + 1)); };
        glm::vec3 p(0.2f + 3.6f * uniform(), 0.05f + 3.0f * uniform(), 0.2f + 3.6f * uniform());
        glm::vec3 n(0.0f);
        if (cache % 3 == 0) n = glm::vec3(0, 1, 0), p.y = 0.01f;
        if (cache % 3 == 1) n = glm::vec3(cache % 2 ? 1.0f : -1.0f, 0, 0);
        const LinkRays::Directions dirs{dx.data(), dy.data(), dz.data()};
        const rt::RayFan fan = pattern.fan(*accel, cache, p, n, dirs);
        accel->intersectFan(fan, hits);
        // Traced hits almost never land on a raster cell wholly beyond a hypotenuse (those
        // hold no owner; the locator's full lookup answers a hit there): move every 7th hit
        // of some fans there, so that steps with such a stray hit are compared too.
        if (cache % 4 == 3)
          for (std::uint32_t i = 0; i < count; i += 7) u[i] = v[i] = 0.97f;
        const Outcome want = creditedRayByRay(fan, hits, double_sided, locator);
        for (const HitCreditKernel kernel : kernels) {
          Outcome got;
          got.samples.assign(count + kHitCreditSlack, 0);
          got.escaped.assign(count, -1.0f);
          got.credit = creditHits(fan, hits, double_sided.data(), locator, slots.data(), got.escaped.data(),
                                  got.samples.data(), kernel);
          got.samples.resize(got.credit.sampled);
          const std::string where = std::string(kernel == HitCreditKernel::kScalar ? "scalar" : "AVX-512") +
                                    " kernel, rays " + std::to_string(count) + ", cache " + std::to_string(cache) +
                                    (narrow ? ", 16-bit raster" : ", 32-bit raster") + ", r " +
                                    std::to_string(locator.rasterFactor());
          EXPECT_EQ(got.credit.sampled, want.credit.sampled) << where;
          EXPECT_EQ(got.credit.escaped, want.credit.escaped) << where;
          EXPECT_EQ(got.credit.back_hits, want.credit.back_hits) << where;
          EXPECT_EQ(got.credit.unowned, want.credit.unowned) << where;
          EXPECT_EQ(got.samples, want.samples) << where;
          EXPECT_EQ(0, std::memcmp(got.escaped.data(), want.escaped.data(), count * sizeof(float))) << where;
        }
        kinds.sampled += want.credit.sampled;
        kinds.escaped += want.credit.escaped;
        kinds.back_hits += want.credit.back_hits;
        for (std::uint32_t i = 0; i < count; ++i) {
          if (mesh[i] == rt::kNoHit) continue;
          const std::uint32_t slot = locator.rasterSlot(mesh[i], triangle[i], u[i], v[i]);
          stray += (slot == kNoSurfel || locator.slotOwner(slot) == kNoSurfel) ? 1 : 0;
        }
        ++fans;
      }
    }
  }
  EXPECT_EQ(fans, 3u * 3u * 60u);
  EXPECT_GT(kinds.sampled, 0u);
  EXPECT_GT(kinds.escaped, 0u);
  EXPECT_GT(kinds.back_hits, 0u);
  EXPECT_GT(stray, 0u) << "no hit took the locator's full lookup: the fallback path went untested";
}

TEST(HitCredit, EveryKernelCreditsAsTheLocatorRayByRay) { expectEveryKernelCreditsAsTheLocator(8); }
TEST(HitCredit, EveryKernelCreditsAsTheLocatorRayByRayWithFewMeshes) { expectEveryKernelCreditsAsTheLocator(2); }

}  // namespace
}  // namespace lightlink::links
