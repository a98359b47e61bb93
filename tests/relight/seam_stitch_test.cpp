// Seam stitching (core/relight/seam_stitch.h): texels on the two sides of a smooth UV seam
// agree after the relight; creases are left alone; texels away from seams keep their values.
#include <cmath>
#include <numbers>

#include <gtest/gtest.h>

#include "tests/relight/relight_fixture.h"

namespace lightlink::relight {
namespace {

using namespace lightlink::relight::testing;

LightSet lamp(glm::vec3 at, float cd = 20.0f) {
  LightSet l;
  scene::Light p;
  p.position = at;
  p.intensity = cd;
  EXPECT_TRUE(l.add({"lamp", p, true}));
  return l;
}

// A 2 m floor whose two triangles sit apart in the atlas (their shared diagonal is a seam),
// under a lamp near one corner so the light changes across the seam.
std::unique_ptr<Baked> splitFloor() {
  scene::Scene s;
  const int m = addMaterial(s, glm::vec3(0.6f));
  scene::MeshInstance q;
  q.name = "split floor";
  const glm::vec3 a{-1, 0, -1}, b{-1, 0, 1}, c{1, 0, 1}, d{1, 0, -1};
  q.positions = {a, b, c, a, c, d};
  q.normals.assign(6, glm::vec3(0, 1, 0));
  // Triangle 1 in the left half of the atlas, triangle 2 in the right half, each with a margin.
  q.uv1 = {{0.05f, 0.05f}, {0.05f, 0.45f}, {0.45f, 0.45f}, {0.55f, 0.05f}, {0.95f, 0.45f}, {0.95f, 0.05f}};
  q.indices = {0, 1, 2, 3, 4, 5};
  q.material = m;
  s.meshes.push_back(q);
  auto o = smallOptions();
  o.lightmap_resolution = 32;
  return Baked::make(std::move(s), o);
}

TEST(SeamStitch, MakesTheTwoSidesOfASeamAgree) {
  auto b = splitFloor();
  ASSERT_TRUE(b);
  Relighter r = b->relighter();
  const LightSet lights = lamp({-0.8f, 0.6f, 0.7f});
  auto off = r.relight(lights, {.max_bounces = 0, .stitch_seams = false});
  ASSERT_TRUE(off);
  EXPECT_EQ(off->seams.edges, 0u);  // not stitched, not measured
  auto on = r.relight(lights, {.max_bounces = 0});
  ASSERT_TRUE(on);
  EXPECT_EQ(on->seams.edges, 1u);
  EXPECT_GT(on->seams.texels, 0u);
  EXPECT_EQ(on->direct_seams.edges, 1u);
  // Measured on the direct light (lit unevenly by the lamp): 0.086 before, 0.004 after.
  EXPECT_GT(on->direct_seams.jump_before, 0.02) << "the scene has no seam jump to remove";
  EXPECT_LT(on->direct_seams.jump_after, 0.15 * on->direct_seams.jump_before);
  EXPECT_LE(on->seams.jump_after, on->seams.jump_before);
  // Texels far from the seam are untouched.
  std::size_t changed = 0;
  for (std::size_t t = 0; t < on->direct.size(); ++t) changed += on->direct[t] != off->direct[t];
  EXPECT_GT(changed, 0u);
  EXPECT_LE(changed, on->direct_seams.texels);
  EXPECT_LT(changed, on->direct.size() / 4);
}

TEST(SeamStitch, LeavesCreasesAlone) {
  scene::Scene s;
  const int m = addMaterial(s, glm::vec3(0.6f));
  addBox(s, {-0.5f, 0.0f, -0.5f}, {0.5f, 1.0f, 0.5f}, /*inward=*/false, m);
  auto b = Baked::make(std::move(s), smallOptions());
  ASSERT_TRUE(b);
  Relighter r = b->relighter();
  auto res = r.relight(lamp({1.5f, 2.0f, 1.0f}), {.max_bounces = 1});
  ASSERT_TRUE(res);
  EXPECT_EQ(res->seams.edges, 0u);  // a box's UV seams are all at its 90-degree edges
}

TEST(SeamStitch, StitchesATessellatedCylinder) {
  scene::Scene s;
  const int m = addMaterial(s, glm::vec3(0.6f));
  scene::MeshInstance c;
  c.name = "cylinder";
  constexpr int kSegments = 16;
  for (int i = 0; i <= kSegments; ++i) {
    const float a = 2.0f * std::numbers::pi_v<float> * float(i % kSegments) / kSegments;
    const glm::vec3 rim{std::cos(a), 0.0f, std::sin(a)};
    c.positions.push_back(rim);
    c.positions.push_back(rim + glm::vec3(0, 2, 0));
    c.normals.push_back(rim);
    c.normals.push_back(rim);
  }
  for (std::uint32_t i = 0; i < kSegments; ++i) {
    const std::uint32_t b0 = 2 * i, t0 = b0 + 1, b1 = b0 + 2, t1 = b0 + 3;
    c.indices.insert(c.indices.end(), {b0, t0, t1, b0, t1, b1});  // outward
  }
  c.material = m;
  s.meshes.push_back(c);
  auto b = Baked::make(std::move(s), smallOptions());
  ASSERT_TRUE(b);
  Relighter r = b->relighter();
  auto res = r.relight(lamp({2.5f, 1.5f, 0.5f}), {.max_bounces = 1});
  ASSERT_TRUE(res);
  EXPECT_GT(res->seams.edges, 0u);
  EXPECT_LE(res->seams.jump_after, res->seams.jump_before);
  // Measured: 0.87 before (the seam runs along the lamp's terminator), 0.003 after.
  EXPECT_GT(res->direct_seams.jump_before, 0.1);
  EXPECT_LT(res->direct_seams.jump_after, 0.05 * res->direct_seams.jump_before);
}

}  // namespace
}  // namespace lightlink::relight
