// Surfel placement: exact count, area conservation, surfels on their triangles, relaxation
// that improves spacing without leaving the surface, attributes from materials and
// textures, determinism across thread counts, rejection of bad input.
#include "core/surfels/surfels.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <numeric>

#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include "core/scene/load.h"
#include "core/scene/material_eval.h"
#include "core/surfels/surface.h"
#include "tests/common/testing.h"
#include "tests/surfels/test_scenes.h"

namespace lightlink::surfels {
namespace {

using testing::addBox;
using testing::finishScene;
using testing::quadMesh;
using testing::staticArea;

scene::Scene boxScene() {
  scene::Scene s;
  addBox(s, "box", glm::vec3(-1.0f, 0.0f, -0.5f), glm::vec3(1.0f, 1.0f, 2.5f), 4);
  // A fan of 5000 tiny triangles (each far below one surfel's area) and one long sliver.
  scene::MeshInstance fan;
  fan.name = "fan";
  fan.positions.push_back(glm::vec3(0.0f, 3.0f, 0.0f));
  fan.normals.push_back(glm::vec3(0, 1, 0));
  for (int i = 0; i <= 5000; ++i) {
    const float a = 0.5f * float(i) / 5000.0f;
    fan.positions.push_back(glm::vec3(0.0f, 3.0f, 0.0f) + 0.3f * glm::vec3(std::cos(a), 0.0f, -std::sin(a)));
    fan.normals.push_back(glm::vec3(0, 1, 0));
    if (i > 0) fan.indices.insert(fan.indices.end(), {0u, std::uint32_t(i), std::uint32_t(i + 1)});
  }
  s.meshes.push_back(fan);
  scene::MeshInstance sliver;
  sliver.name = "sliver";
  sliver.positions = {glm::vec3(-3, 0, 0), glm::vec3(3, 0, 0), glm::vec3(0, 0.001f, 0)};
  sliver.normals.assign(3, glm::vec3(0, 0, 1));
  sliver.indices = {0, 1, 2};
  s.meshes.push_back(sliver);
  finishScene(s);
  return s;
}

Surfels place(const scene::Scene& s, SurfelOptions o) {
  Expected<Surfels> r = placeSurfels(s, o);
  EXPECT_TRUE(r.hasValue()) << r.status().toString();
  return r.hasValue() ? std::move(r).value() : Surfels{};
}

double areaSum(const Surfels& s) {
  double a = 0.0;
  for (float x : s.area) a += x;
  return a;
}

// Count is exactly nS (not +-1) and the areas add up to the static area.
TEST(Surfels, ExactCountAndAreaSum) {
  const scene::Scene s = boxScene();
  const double area = staticArea(s);
  for (std::uint32_t n : {1u, 7u, 100u, 5000u, 20000u}) {
    SurfelOptions o;
    o.count = n;
    o.relaxation_iterations = 3;
    const Surfels surfels = place(s, o);
    ASSERT_EQ(surfels.size(), n);
    EXPECT_NEAR(areaSum(surfels), area, 1e-5 * area) << "n=" << n;
    for (float a : surfels.area) EXPECT_FLOAT_EQ(a, float(area / n));
  }
}

// 10000 equal tiny triangles, 64 surfels: area accumulates over ~156 triangles per surfel
// and surfel j lands on the triangle under its slice midpoint, floor((2j + 1) * 78.125).
TEST(Surfels, SmallTrianglesAccumulateUntilTheySpawn) {
  scene::Scene s;
  s.meshes.push_back(quadMesh("strip", glm::vec3(0.0f), glm::vec3(10, 0, 0), glm::vec3(0, 0, -0.01f), 5000, 1));
  finishScene(s);
  SurfelOptions o;
  o.count = 64;
  o.relaxation_iterations = 0;
  const Surfels surfels = place(s, o);
  ASSERT_EQ(surfels.size(), 64u);
  for (std::uint32_t j = 0; j < 64; ++j)
    EXPECT_EQ(surfels.triangle[j], std::uint32_t(std::floor((2 * j + 1) * 78.125))) << j;
  EXPECT_NEAR(areaSum(surfels), 0.1, 1e-6);
}

// Position is on the owning triangle (reconstructible from the barycentrics, in the plane,
// inside), normals are unit, and no surfel crossed a crease onto another face of the box.
TEST(Surfels, RelaxedSurfelsStayOnTheirTriangles) {
  const scene::Scene s = boxScene();
  SurfelOptions o;
  o.count = 6000;
  o.relaxation_iterations = 10;
  const Surfels surfels = place(s, o);
  const float eps = 1e-5f * s.scale;
  std::map<std::uint32_t, int> per_mesh;
  for (std::size_t j = 0; j < surfels.size(); ++j) {
    const scene::MeshInstance& m = s.meshes[surfels.mesh[j]];
    const std::uint32_t* idx = &m.indices[3 * std::size_t(surfels.triangle[j])];
    const glm::vec3 p0 = m.positions[idx[0]], p1 = m.positions[idx[1]], p2 = m.positions[idx[2]];
    const glm::vec2 b = surfels.barycentric[j];
    EXPECT_GE(b.x, 0.0f);
    EXPECT_GE(b.y, 0.0f);
    EXPECT_LE(b.x + b.y, 1.0f + 1e-6f);
    const glm::vec3 rebuilt = (1.0f - b.x - b.y) * p0 + b.x * p1 + b.y * p2;
    EXPECT_LT(glm::length(rebuilt - surfels.position[j]), eps);
    const glm::vec3 n = glm::normalize(glm::cross(p1 - p0, p2 - p0));
    EXPECT_LT(std::abs(glm::dot(n, surfels.position[j] - p0)), eps);
    EXPECT_NEAR(glm::length(surfels.normal[j]), 1.0f, 1e-5f);
    ++per_mesh[surfels.mesh[j]];
  }
  // Relaxation cannot move surfels between box faces, so each face keeps its share.
  const double slice = staticArea(s) / o.count;
  for (std::uint32_t mi = 0; mi < 6; ++mi) {
    scene::Scene one;
    one.meshes.push_back(s.meshes[mi]);
    EXPECT_NEAR(per_mesh[mi], staticArea(one) / slice, 1.0) << s.meshes[mi].name;
  }
}

struct Spacing {
  float min_nn = 0.0f;  // smallest nearest-neighbour distance
  float cv = 0.0f;      // coefficient of variation of nearest-neighbour distances
};
Spacing spacing(const Surfels& s) {
  std::vector<float> nn(s.size(), std::numeric_limits<float>::max());
  for (std::size_t i = 0; i < s.size(); ++i)
    for (std::size_t j = i + 1; j < s.size(); ++j) {
      const float d = glm::length(s.position[i] - s.position[j]);
      nn[i] = std::min(nn[i], d);
      nn[j] = std::min(nn[j], d);
    }
  const double mean = std::accumulate(nn.begin(), nn.end(), 0.0) / double(nn.size());
  double var = 0.0;
  for (float d : nn) var += (d - mean) * (d - mean);
  return {*std::min_element(nn.begin(), nn.end()), float(std::sqrt(var / double(nn.size())) / mean)};
}

// On a plane of 2 triangles and on the same plane cut into 3200 triangles (surfels must
// migrate across edges to even out), relaxation raises the smallest neighbour distance and
// lowers the spread of neighbour distances.
TEST(Surfels, RelaxationImprovesUniformity) {
  for (int cells : {1, 40}) {
    scene::Scene s;
    s.meshes.push_back(quadMesh("plane", glm::vec3(0.0f), glm::vec3(1, 0, 0), glm::vec3(0, 1, 0), cells, cells));
    finishScene(s);
    SurfelOptions o;
    o.count = 2000;
    o.relaxation_iterations = 0;
    const Spacing before = spacing(place(s, o));
    o.relaxation_iterations = 10;
    const Surfels relaxed = place(s, o);
    const Spacing after = spacing(relaxed);
    const float ideal = float(std::sqrt(2.0 / (std::sqrt(3.0) * o.count)));
    std::printf("[ surfels ] %d cells: min NN %.4f -> %.4f, NN CV %.3f -> %.3f (ideal spacing %.4f)\n",
                cells, before.min_nn, after.min_nn, before.cv, after.cv, ideal);
    EXPECT_GT(after.min_nn, 1.5f * before.min_nn) << cells;
    // Surfels clamped to their own small triangles (no crossing) reach only ~0.36 of the
    // ideal spacing on the 40 x 40 plane; crossing edges reaches ~0.65.
    EXPECT_GT(after.min_nn, 0.5f * ideal) << cells;
    EXPECT_LT(after.cv, 0.7f * before.cv) << cells;
    EXPECT_NEAR(areaSum(relaxed), 1.0, 1e-5);
  }
}

TEST(Surfels, DeterministicAcrossThreadCounts) {
  const scene::Scene s = boxScene();
  SurfelOptions o;
  o.count = 4000;
  o.relaxation_iterations = 6;
  auto run = [&](int threads) {
    tbb::global_control limit(tbb::global_control::max_allowed_parallelism, std::size_t(threads));
    return place(s, o);
  };
  const Surfels a = run(1), b = run(2);
  ASSERT_EQ(a.size(), b.size());
  for (std::size_t j = 0; j < a.size(); ++j) {
    ASSERT_EQ(a.position[j], b.position[j]) << j;
    ASSERT_EQ(a.triangle[j], b.triangle[j]) << j;
    ASSERT_EQ(a.mesh[j], b.mesh[j]) << j;
  }
  o.seed = 1;
  const Surfels c = place(s, o);
  std::size_t moved = 0;
  for (std::size_t j = 0; j < a.size(); ++j) moved += a.position[j] != c.position[j];
  EXPECT_GT(moved, a.size() / 2) << "the seed should change the Halton starts";
}

TEST(Surfels, DynamicMeshesIgnored) {
  scene::Scene s;
  s.meshes.push_back(quadMesh("static", glm::vec3(0.0f), glm::vec3(1, 0, 0), glm::vec3(0, 1, 0), 2, 2));
  s.meshes.push_back(quadMesh("dynamic", glm::vec3(0, 0, 1), glm::vec3(5, 0, 0), glm::vec3(0, 5, 0), 2, 2));
  s.meshes[1].is_static = false;
  finishScene(s);
  SurfelOptions o;
  o.count = 500;
  const Surfels surfels = place(s, o);
  ASSERT_EQ(surfels.size(), 500u);
  for (std::uint32_t m : surfels.mesh) EXPECT_EQ(m, 0u);
  EXPECT_NEAR(areaSum(surfels), 1.0, 1e-5);

  s.meshes[0].is_static = false;  // nothing static left: an empty set, not an error
  const Surfels none = place(s, o);
  EXPECT_TRUE(none.empty());
  EXPECT_TRUE(place(scene::Scene{}, o).empty());
}

TEST(Surfels, AttributesFromMaterialsAndTextures) {
  scene::Scene s;
  scene::Material red;
  red.base_color_factor = glm::vec4(0.8f, 0.1f, 0.1f, 1.0f);
  scene::Material lamp;
  lamp.base_color_factor = glm::vec4(0.5f);
  lamp.emissive_factor = glm::vec3(1.0f, 0.5f, 0.25f);
  lamp.emissive_strength = 4.0f;
  scene::Material textured;  // left half of the texture red, right half green
  textured.base_color_texture.texture = 0;
  scene::Texture tex;
  tex.width = 2;
  tex.height = 1;
  tex.rgba8 = {255, 0, 0, 255, 0, 255, 0, 255};
  tex.nearest = true;
  tex.wrap_s = tex.wrap_t = 33071;
  s.textures.push_back(tex);
  s.materials = {red, lamp, textured};
  s.meshes.push_back(quadMesh("red", glm::vec3(0.0f), glm::vec3(1, 0, 0), glm::vec3(0, 1, 0), 1, 1, 0));
  s.meshes.push_back(quadMesh("lamp", glm::vec3(0, 0, 2), glm::vec3(0, 1, 0), glm::vec3(1, 0, 0), 1, 1, 1));
  s.meshes.push_back(quadMesh("textured", glm::vec3(2, 0, 0), glm::vec3(1, 0, 0), glm::vec3(0, 1, 0), 3, 3, 2,
                              /*lightmap_uv=*/false));
  finishScene(s);
  SurfelOptions o;
  o.count = 900;
  const Surfels surfels = place(s, o);
  int seen[3] = {0, 0, 0};
  for (std::size_t j = 0; j < surfels.size(); ++j) {
    const std::uint32_t m = surfels.mesh[j];
    ++seen[m];
    const glm::vec3 p = surfels.position[j];
    if (m == 0) {
      EXPECT_EQ(surfels.albedo[j], glm::vec3(0.8f, 0.1f, 0.1f));
      EXPECT_EQ(surfels.emission[j], glm::vec3(0.0f));
      // uv1 = (s, t) of the quad, which here is the position's (x, y).
      EXPECT_NEAR(surfels.lightmap_uv[j].x, p.x, 1e-5f);
      EXPECT_NEAR(surfels.lightmap_uv[j].y, p.y, 1e-5f);
      EXPECT_NEAR(surfels.normal[j].z, 1.0f, 1e-6f);
    } else if (m == 1) {
      EXPECT_EQ(surfels.emission[j], glm::vec3(4.0f, 2.0f, 1.0f));
      EXPECT_NEAR(surfels.normal[j].z, -1.0f, 1e-6f);
    } else {
      EXPECT_EQ(surfels.lightmap_uv[j], glm::vec2(-1.0f));
      const float u = p.x - 2.0f;
      if (u < 0.49f) {
        EXPECT_EQ(surfels.albedo[j], glm::vec3(1, 0, 0)) << u;
      } else if (u > 0.51f) {
        EXPECT_EQ(surfels.albedo[j], glm::vec3(0, 1, 0)) << u;
      }
    }
  }
  for (int c : seen) EXPECT_NEAR(c, 300, 1);
}

TEST(Surfels, RejectsInvalidInput) {
  const scene::Scene s = boxScene();
  SurfelOptions o;
  o.count = 0;
  EXPECT_EQ(placeSurfels(s, o).status().code(), Code::kInvalidInput);
  o.count = 10;
  o.relaxation_step = std::numeric_limits<float>::quiet_NaN();
  EXPECT_EQ(placeSurfels(s, o).status().code(), Code::kInvalidInput);
  o.relaxation_step = 0.3f;
  o.relaxation_iterations = -1;
  EXPECT_EQ(placeSurfels(s, o).status().code(), Code::kInvalidInput);
  o.relaxation_iterations = 2;

  scene::Scene bad = s;
  bad.meshes[2].positions[3].y = std::numeric_limits<float>::infinity();
  const auto r = placeSurfels(bad, o);
  EXPECT_EQ(r.status().code(), Code::kInvalidInput);
  EXPECT_NE(r.status().message().find(bad.meshes[2].name), std::string::npos) << r.status().message();
  bad = s;
  bad.meshes[0].indices[4] = 100000;
  EXPECT_EQ(placeSurfels(bad, o).status().code(), Code::kInvalidInput);
}

// Edges are found by position, so a quad whose two triangles do not share vertex indices
// (split at a seam) is still one surface, while a crease is not crossed.
TEST(StaticSurface, AdjacencyWeldsSplitVerticesAndStopsAtCreases) {
  scene::Scene s;
  scene::MeshInstance m;
  m.name = "split";
  m.positions = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 0, 0}, {1, 1, 0}, {0, 1, 0}, {1, 0, 0}, {1, 1, 0}, {1, 0, 1}};
  m.indices = {0, 1, 2, 3, 4, 5, 6, 8, 7};
  s.meshes.push_back(m);
  const Expected<StaticSurface> surface = buildStaticSurface(s);
  ASSERT_TRUE(surface.hasValue());
  EXPECT_EQ(surface->neighbour[0 * 3 + 1], 1);  // edge (p2, p0) of triangle 0
  EXPECT_EQ(surface->neighbour[1 * 3 + 2], 0);  // edge (p0, p1) of triangle 1
  EXPECT_EQ(surface->neighbour[0 * 3 + 0], 2);  // edge (1,0,0)-(1,1,0), shared with the wall
  // Walking from triangle 0 towards -x crosses into triangle 1 (coplanar) ...
  std::uint32_t t = 0;
  glm::vec2 uv(0.2f, 0.1f);  // p = (0.3, 0.1, 0)
  moveOnSurface(*surface, t, uv, glm::vec3(-0.25f, 0.5f, 0.0f), 0.99f);
  EXPECT_EQ(t, 1u);
  EXPECT_LT(glm::length(surface->pointAt(t, uv) - glm::vec3(0.05f, 0.6f, 0.0f)), 1e-5f);
  // ... but walking towards +x stops on the crease with the wall.
  t = 0;
  uv = glm::vec2(0.2f, 0.1f);
  moveOnSurface(*surface, t, uv, glm::vec3(2.0f, 0.0f, 0.0f), 0.99f);
  EXPECT_EQ(t, 0u);
  EXPECT_NEAR(surface->pointAt(t, uv).x, 1.0f, 1e-6f);
}

}  // namespace
}  // namespace lightlink::surfels

namespace lightlink::surfels {
namespace {

// Issue 46: a MASK cut-out has no surfels in its holes (no ray can hit them; a surfel there
// would reflect light from surface that is not there), and the rest keep their area slice,
// so the card's surfels cover its opaque half. tests/data/alpha/alpha_cards.gltf: an 8 x 8
// checker card, half of its squares cut out.
TEST(Surfels, NoneInAlphaCutOuts) {
  auto scene = scene::loadScene((lightlink::testing::sourceDir() / "tests/data/alpha/alpha_cards.gltf").string());
  ASSERT_TRUE(scene) << scene.status().toString();
  SurfelOptions o;
  o.count = 8192;
  auto s = placeSurfels(*scene, o);
  ASSERT_TRUE(s) << s.status().toString();
  std::uint32_t card = 0;
  while (card < scene->meshes.size() && scene->meshes[card].name.rfind("checker_card", 0) != 0) ++card;
  ASSERT_LT(card, scene->meshes.size());
  double card_area = 0.0;
  const auto& m = scene->meshes[card];
  for (std::size_t t = 0; t < m.triangleCount(); ++t) {
    const glm::vec3 a = m.positions[m.indices[3 * t]], b = m.positions[m.indices[3 * t + 1]],
                    c = m.positions[m.indices[3 * t + 2]];
    card_area += 0.5 * glm::length(glm::cross(b - a, c - a));
  }
  double on_card = 0.0;
  std::size_t in_holes = 0;
  for (std::size_t j = 0; j < s->size(); ++j) {
    if (s->mesh[j] != card) continue;
    on_card += s->area[j];
    in_holes += scene::cutOutAt(*scene, m, s->triangle[j], s->barycentric[j]);
  }
  EXPECT_EQ(in_holes, 0u);
  EXPECT_LT(s->size(), std::size_t(o.count));  // the holes' surfels are gone
  // A double-sided card is covered once per side (surface.h).
  const double sides = scene->materialOf(m).double_sided ? 2.0 : 1.0;
  EXPECT_NEAR(on_card / (sides * card_area), 0.5, 0.08) << "surfel area on the card / its area";
}

// A double-sided sheet is two surfaces: each side gets surfels in proportion to its area,
// facing that side (whatever way the vertex normals point), and the total area counts both.
TEST(Surfels, EachSideOfADoubleSidedSheetHasItsOwn) {
  scene::Scene s;
  scene::Material one, two;
  one.name = "one", two.name = "two";
  two.double_sided = true;
  s.materials = {one, two};
  s.meshes.push_back(quadMesh("floor", glm::vec3(-1, 0, -1), glm::vec3(0, 0, 2), glm::vec3(2, 0, 0), 4, 4, 0));
  scene::MeshInstance sheet =
      quadMesh("sheet", glm::vec3(-0.5f, 0.5f, -0.5f), glm::vec3(0, 0, 1), glm::vec3(1, 0, 0), 2, 2, 1);
  for (auto& n : sheet.normals) n = -n;  // vertex normals against the winding: still two sides
  s.meshes.push_back(sheet);
  finishScene(s);
  SurfelOptions o;
  o.count = 5000;
  const Surfels out = place(s, o);
  ASSERT_EQ(out.size(), 5000u);
  EXPECT_NEAR(areaSum(out), 4.0 + 2.0 * 1.0, 1e-3);  // the floor, and the sheet twice
  std::size_t up = 0, down = 0;
  for (std::size_t j = 0; j < out.size(); ++j) {
    if (out.mesh[j] != 1) continue;
    EXPECT_NEAR(std::abs(out.normal[j].y), 1.0f, 1e-5f);
    (out.normal[j].y > 0.0f ? up : down) += 1;
  }
  EXPECT_NEAR(double(up) / 5000.0, 1.0 / 6.0, 0.01);
  EXPECT_NEAR(double(down) / 5000.0, 1.0 / 6.0, 0.01);
  const Expected<StaticSurface> surface = buildStaticSurface(s);
  ASSERT_TRUE(surface);
  ASSERT_EQ(surface->size(), 32u + 8u + 8u);
  for (std::size_t t = 40; t < 48; ++t) {
    EXPECT_TRUE(surface->back[t]);
    EXPECT_EQ(surface->normal[t], -surface->normal[t - 8]);
    for (int k = 0; k < 3; ++k) {
      const std::int32_t front_nb = surface->neighbour[3 * (t - 8) + k], back_nb = surface->neighbour[3 * t + k];
      EXPECT_EQ(back_nb, front_nb < 0 ? -1 : front_nb + 8) << t << " " << k;
    }
  }
}

}  // namespace
}  // namespace lightlink::surfels
