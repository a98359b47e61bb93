#include "core/caches/caches.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <string>

#include <gtest/gtest.h>
#include <tbb/global_control.h>

namespace lightlink::caches {
namespace {

using scene::MeshInstance;
using scene::Scene;

// Adds a quad p0..p3 (counter-clockwise seen from its front) with lightmap UVs uv0..uv3.
void addQuad(Scene& s, glm::vec3 p0, glm::vec3 p1, glm::vec3 p2, glm::vec3 p3,
             std::array<glm::vec2, 4> uv = {glm::vec2(0, 0), {1, 0}, {1, 1}, {0, 1}}, bool with_uv = true) {
  MeshInstance m;
  m.name = "quad" + std::to_string(s.meshes.size());
  m.positions = {p0, p1, p2, p3};
  const glm::vec3 n = glm::normalize(glm::cross(p1 - p0, p2 - p0));
  m.normals = {n, n, n, n};
  if (with_uv) m.uv1 = {uv[0], uv[1], uv[2], uv[3]};
  m.indices = {0, 1, 2, 0, 2, 3};
  s.meshes.push_back(m);
}

// A closed axis-aligned box with outward faces (a solid block), no lightmap UVs.
void addSolidBox(Scene& s, glm::vec3 lo, glm::vec3 hi) {
  const glm::vec3 c[8] = {{lo.x, lo.y, lo.z}, {hi.x, lo.y, lo.z}, {hi.x, hi.y, lo.z}, {lo.x, hi.y, lo.z},
                          {lo.x, lo.y, hi.z}, {hi.x, lo.y, hi.z}, {hi.x, hi.y, hi.z}, {lo.x, hi.y, hi.z}};
  const int faces[6][4] = {{0, 3, 2, 1}, {4, 5, 6, 7}, {0, 1, 5, 4}, {2, 3, 7, 6}, {0, 4, 7, 3}, {1, 2, 6, 5}};
  for (const auto& f : faces) addQuad(s, c[f[0]], c[f[1]], c[f[2]], c[f[3]], {}, false);
}

void finish(Scene& s) {
  s.bounds = Aabb();
  for (const auto& m : s.meshes)
    for (const auto& p : m.positions) s.bounds.grow(p);
  s.scale = s.bounds.diagonal();
}

rt::Accel buildAccel(const Scene& s) {
  auto a = rt::Accel::build(s);
  EXPECT_TRUE(a) << a.status().toString();
  return std::move(a).value();
}

// A 1 m floor in the xz plane facing +y, lightmap u = x, v = z.
Scene floorScene() {
  Scene s;
  addQuad(s, {0, 0, 0}, {0, 0, 1}, {1, 0, 1}, {1, 0, 0}, {glm::vec2(0, 0), {0, 1}, {1, 1}, {1, 0}});
  finish(s);
  return s;
}

TEST(LightmapCaches, FullQuadGetsOneValidCachePerTexelAtTheTexelCentre) {
  Scene s = floorScene();
  auto accel = buildAccel(s);
  auto caches = placeLightmapCaches(s, accel, {.resolution = 8});
  ASSERT_TRUE(caches) << caches.status().toString();
  ASSERT_EQ(caches->size(), 64u);
  EXPECT_EQ(caches->validCount(), 64u);
  for (std::size_t i = 0; i < caches->size(); ++i) {
    const std::uint32_t t = caches->texel[i];
    const float u = (float(t % 8) + 0.5f) / 8.0f, v = (float(t / 8) + 0.5f) / 8.0f;
    EXPECT_NEAR(caches->position[i].x, u, 1e-5f);
    EXPECT_NEAR(caches->position[i].z, v, 1e-5f);
    EXPECT_NEAR(caches->normal[i].y, 1.0f, 1e-6f);
    EXPECT_EQ(caches->cache_of_texel[t], static_cast<std::int32_t>(i));
  }
}

TEST(LightmapCaches, ConservativeCoverageKeepsEdgeTexelsOnTheTriangle) {
  // One triangle under u/1 + v/0.7 <= 1: its long edge cuts texels at odd angles.
  Scene s;
  MeshInstance m;
  m.positions = {{0, 0, 0}, {1, 0, 0}, {0, 0, 1}};
  m.normals = {{0, 1, 0}, {0, 1, 0}, {0, 1, 0}};
  m.uv1 = {{0, 0}, {1, 0}, {0, 0.7f}};
  m.indices = {0, 2, 1};  // faces +y
  s.meshes.push_back(m);
  finish(s);
  auto accel = buildAccel(s);
  const int res = 16;
  auto caches = placeLightmapCaches(s, accel, {.resolution = res});
  ASSERT_TRUE(caches);
  std::size_t centre_inside = 0, grazing = 0;
  for (int y = 0; y < res; ++y) {
    for (int x = 0; x < res; ++x) {
      const float hyp_x = float(res), hyp_y = 0.7f * float(res);
      const bool inside = (x + 0.5f) / hyp_x + (y + 0.5f) / hyp_y <= 1.0f;
      const bool touches = x / hyp_x + y / hyp_y < 1.0f;  // lower-left corner inside
      const std::int32_t c = caches->cache_of_texel[y * res + x];
      if (touches) {
        ASSERT_GE(c, 0) << "texel " << x << "," << y << " touches the triangle but has no cache";
        const glm::vec3 p = caches->position[c];
        EXPECT_LE(p.x + p.z, 1.0f + 1e-5f) << "cache left the triangle";
        EXPECT_GE(std::min(p.x, p.z), -1e-6f);
        (inside ? centre_inside : grazing)++;
      } else {
        EXPECT_EQ(c, -1) << "texel " << x << "," << y;
      }
    }
  }
  EXPECT_GT(grazing, 0u);
  EXPECT_EQ(centre_inside + grazing, caches->size());
}

TEST(LightmapCaches, TexelsUnderASolidBlockArePushedOutOrInvalid) {
  Scene s = floorScene();
  addSolidBox(s, {-0.1f, -0.1f, -0.1f}, {0.3f, 0.5f, 1.1f});  // covers x < 0.3 of the floor
  finish(s);
  auto accel = buildAccel(s);
  auto caches = placeLightmapCaches(s, accel, {.resolution = 10});
  ASSERT_TRUE(caches);
  std::size_t invalid = 0, pushed = 0;
  for (std::size_t i = 0; i < caches->size(); ++i) {
    const glm::vec3 p = caches->position[i];
    if (!caches->valid[i]) {
      ++invalid;
      continue;
    }
    pushed += caches->pushed[i];
    EXPECT_FALSE(p.x < 0.3f - 1e-4f && p.y < 0.5f && p.y > -0.1f) << "valid cache inside the block at x=" << p.x;
  }
  EXPECT_GT(invalid + pushed, 0u);
  // Texels far from the block see open sky and are untouched.
  const std::int32_t far = caches->cache_of_texel[5 * 10 + 9];
  ASSERT_GE(far, 0);
  EXPECT_TRUE(caches->valid[far]);
  EXPECT_FALSE(caches->pushed[far]);
  // Every invalid cache is filled, from valid neighbours where it has them.
  const FillPlan fill = planLightmapFill(*caches);
  EXPECT_EQ(fill.target.size(), invalid);
  std::vector<std::uint8_t> has_value = caches->valid;
  for (std::size_t k = 0; k < fill.target.size(); ++k) {
    ASSERT_LT(fill.source_begin[k], fill.source_begin[k + 1]);
    for (std::uint32_t j = fill.source_begin[k]; j < fill.source_begin[k + 1]; ++j)
      EXPECT_TRUE(has_value[fill.source[j]]) << "filled from a cache with no value yet";
    has_value[fill.target[k]] = 1;
  }
  EXPECT_EQ(std::count(has_value.begin(), has_value.end(), 0), 0);
}

TEST(LightmapCaches, DeterministicAcrossThreadCounts) {
  Scene s = floorScene();
  addSolidBox(s, {0.2f, 0.0f, 0.2f}, {0.6f, 0.4f, 0.6f});
  finish(s);
  auto accel = buildAccel(s);
  auto run = [&](int threads) {
    tbb::global_control limit(tbb::global_control::max_allowed_parallelism, threads);
    return std::move(placeLightmapCaches(s, accel, {.resolution = 32})).value();
  };
  const auto a = run(1), b = run(2);
  ASSERT_EQ(a.size(), b.size());
  EXPECT_EQ(a.texel, b.texel);
  EXPECT_EQ(a.valid, b.valid);
  EXPECT_EQ(a.pushed, b.pushed);
  for (std::size_t i = 0; i < a.size(); ++i) EXPECT_EQ(a.position[i], b.position[i]);
}

TEST(LightmapCaches, RejectsAbsurdParameters) {
  Scene s = floorScene();
  auto accel = buildAccel(s);
  for (int res : {0, -4, 16385}) {
    auto c = placeLightmapCaches(s, accel, {.resolution = res});
    ASSERT_FALSE(c);
    EXPECT_NE(c.status().message().find("resolution"), std::string::npos);
  }
  LightmapCacheOptions bad{.resolution = 8};
  bad.validity.max_backface_fraction = std::nanf("");
  EXPECT_FALSE(placeLightmapCaches(s, accel, bad));
}

TEST(Dilation, FillsGutterTexelsRingByRing) {
  // A quad occupying texels [4, 12) of a 16x16 atlas.
  Scene s;
  addQuad(s, {0, 0, 0}, {0, 0, 1}, {1, 0, 1}, {1, 0, 0},
          {glm::vec2(0.25f, 0.25f), {0.25f, 0.75f}, {0.75f, 0.75f}, {0.75f, 0.25f}});
  finish(s);
  auto accel = buildAccel(s);
  auto caches = placeLightmapCaches(s, accel, {.resolution = 16});
  ASSERT_TRUE(caches);
  ASSERT_EQ(caches->size(), 64u);
  const FillPlan one = planDilation(*caches, 1);
  const FillPlan two = planDilation(*caches, 2);
  // One ring around an 8x8 block is 10*10 - 64 texels, two rings 12*12 - 64.
  EXPECT_EQ(one.target.size(), 36u);
  EXPECT_EQ(two.target.size(), 80u);
  // Corner texel (3,3) of the first ring reads only the diagonal neighbour (4,4).
  const auto it = std::find(one.target.begin(), one.target.end(), 3u * 16 + 3);
  ASSERT_NE(it, one.target.end());
  const std::size_t k = static_cast<std::size_t>(it - one.target.begin());
  ASSERT_EQ(one.source_begin[k + 1] - one.source_begin[k], 1u);
  EXPECT_EQ(one.source[one.source_begin[k]], 4u * 16 + 4);
}

TEST(GridCaches, PointsInsideASolidBlockAreInvalidAndFilled) {
  Scene s;
  addSolidBox(s, {0.35f, 0.35f, 0.35f}, {0.65f, 0.65f, 0.65f});
  addQuad(s, {0, 0, 0}, {0, 0, 1}, {1, 0, 1}, {1, 0, 0});
  finish(s);
  auto accel = buildAccel(s);
  GridCacheOptions opt;
  opt.spacing_m = 0.1f;
  auto grid = placeGridCaches(s, accel, opt);
  ASSERT_TRUE(grid) << grid.status().toString();
  EXPECT_EQ(grid->dims, glm::ivec3(11, 7, 11));  // y extent is 0.65 m
  std::size_t inside = 0;
  for (std::size_t i = 0; i < grid->size(); ++i) {
    const glm::vec3 p = grid->position[i];
    const bool in_block = glm::all(glm::greaterThan(p, glm::vec3(0.36f))) && glm::all(glm::lessThan(p, glm::vec3(0.64f)));
    if (in_block) {
      ++inside;
      EXPECT_FALSE(grid->valid[i]) << "grid cache inside the block marked valid";
    }
  }
  EXPECT_GT(inside, 0u);
  const FillPlan fill = planGridFill(*grid);
  EXPECT_EQ(fill.target.size(), grid->size() - grid->validCount());
  EXPECT_EQ(fill.unreachable, 0u);
}

TEST(GridCaches, RejectsAbsurdSpacing) {
  Scene s = floorScene();
  auto accel = buildAccel(s);
  GridCacheOptions opt;
  opt.spacing_m = std::nanf("");
  EXPECT_FALSE(placeGridCaches(s, accel, opt));
  opt.spacing_m = 1e-6f;
  auto tiny = placeGridCaches(s, accel, opt);
  ASSERT_FALSE(tiny);
  EXPECT_NE(tiny.status().message().find("larger spacing"), std::string::npos);
  opt.spacing_m = -1.0f;
  EXPECT_FALSE(placeGridCaches(s, accel, opt));
}

}  // namespace
}  // namespace lightlink::caches
