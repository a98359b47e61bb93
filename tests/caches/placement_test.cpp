// Cache placement at contacts, corners and under cards (issue 46), judged end to end: the
// baked texel (direct + indirect, after precompute and a converged relight) against the
// reference path tracer at the texel's centre. A cache whose centre fails the validity test
// must stay in its texel's footprint: moved toward its triangle's centroid (15-35 cm on these
// two-triangle walls) it reads the light of another place.
#include <algorithm>
#include <cmath>
#include <memory>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "core/caches/caches.h"
#include "core/reference/compare.h"
#include "core/reference/reference.h"
#include "core/relight/relight.h"
#include "tests/relight/relight_fixture.h"

namespace lightlink::caches {
namespace {

using relight::LightEntry;
using relight::LightSet;
using relight::testing::addBox;
using relight::testing::addMaterial;
using relight::testing::addQuad;
using relight::testing::Baked;

LightEntry pointLight(glm::vec3 pos, float intensity_cd) {
  LightEntry e;
  e.id = "lamp";
  e.light.kind = scene::Light::Kind::kPoint;
  e.light.position = pos;
  e.light.intensity = intensity_cd;
  return e;
}

precompute::PrecomputeOptions placementOptions() {
  precompute::PrecomputeOptions o;
  o.surfels = 16384;
  o.links = 256;
  o.rays = 1024;
  o.lightmap_resolution = 64;
  o.validity_rays = 64;
  o.builder = hierarchy::Builder::kKdMedian;
  o.grid = precompute::GridMode::kOff;
  return o;
}

// One texel as baked and as the reference sees it at its centre.
struct Texel {
  glm::vec3 centre{0.0f}, normal{0.0f};
  float baked = 0.0f;      // luminance of direct + indirect irradiance, lux
  float reference = 0.0f;  // filled by referenceAt
};

// Every texel with a cache: its centre (the cache before any validity move, from a placement
// whose validity test always passes) and its baked total irradiance.
std::vector<Texel> bakeTexels(Baked& b, const LightSet& lights) {
  auto r = b.relighter();
  auto res = r.relight(lights, {.max_bounces = 64, .bounce_threshold = 1e-4f, .emitter_samples = 64});
  EXPECT_TRUE(res) << res.status().toString();
  if (!res) return {};
  auto centres = placeLightmapCaches(b.scene, *b.accel,
                                     {.resolution = b.p.atlas.resolution,
                                      .pages = b.p.atlas.pages,
                                      .validity = {.rays = 1, .max_backface_fraction = 1.0f},
                                      .footprint_search = false});
  EXPECT_TRUE(centres) << centres.status().toString();
  if (!centres) return {};
  std::vector<Texel> out;
  for (std::size_t c = 0; c < centres->size(); ++c) {
    const std::uint32_t t = centres->texel[c];
    if (!res->texel_valid[t]) continue;
    Texel x;
    // A grazed texel's centre is clamped onto its triangle's edge, i.e. onto the contact line,
    // where the reference's rays start inside the other wall: query 2 mm into the triangle.
    const auto& mesh = b.scene.meshes[centres->mesh[c]];
    const std::uint32_t* idx = &mesh.indices[3 * centres->triangle[c]];
    const glm::vec3 centroid = (mesh.positions[idx[0]] + mesh.positions[idx[1]] + mesh.positions[idx[2]]) / 3.0f;
    x.centre = centres->position[c] + 0.002f * glm::normalize(centroid - centres->position[c]);
    x.normal = centres->normal[c];
    x.baked = reference::luminance(res->direct[t] + res->lightmapIndirect(t, x.normal));
    out.push_back(x);
  }
  return out;
}

void referenceAt(const Baked& b, const LightSet& lights, std::vector<Texel>& texels) {
  auto renderer = reference::ReferenceRenderer::create(b.scene, *b.accel, lights);
  ASSERT_TRUE(renderer) << renderer.status().toString();
  std::vector<glm::vec3> p, n;
  for (const auto& t : texels) p.push_back(t.centre), n.push_back(t.normal);
  reference::ReferenceOptions o;
  o.min_samples = 256;
  o.max_samples = 8192;
  o.target_rel_error = 0.015f;
  o.seed = 46;
  auto est = renderer->irradiance({p, n}, o);
  ASSERT_TRUE(est) << est.status().toString();
  for (std::size_t i = 0; i < texels.size(); ++i) texels[i].reference = reference::luminance((*est)[i].total);
}

// A closed room of 12 big triangles (4 x 2.5 x 3 m, y up) with a solid block standing on its
// floor and a point light on one side of the block: wall/floor contacts all round, and a
// shadowed corner where the block's far side meets the floor. Single-sided, and all
// double-sided (as glTF exporters often write rooms): each side then has its own surfels, the
// outer ones never seen, and the room must bake the same.
class ClosedRoom : public ::testing::TestWithParam<bool> {};

TEST_P(ClosedRoom, ContactTexelsMatchTheReference) {
  scene::Scene s;
  const int grey = addMaterial(s, glm::vec3(0.5f), glm::vec3(0.0f), /*double_sided=*/GetParam());
  addBox(s, {0, 0, 0}, {4, 2.5f, 3}, /*inward=*/true, grey);
  const glm::vec3 block_lo(1.5f, 0.0f, 1.0f), block_hi(2.5f, 0.8f, 2.0f);
  addBox(s, block_lo, block_hi, /*inward=*/false, grey);
  auto b = Baked::make(std::move(s), placementOptions());
  ASSERT_TRUE(b);
  LightSet lights;
  ASSERT_TRUE(lights.add(pointLight({0.6f, 1.4f, 1.5f}, 20.0f)));
  std::vector<Texel> all = bakeTexels(*b, lights);
  ASSERT_FALSE(all.empty());

  // World size of a floor texel: the floor's area over its texel count.
  std::size_t floor_texels = 0;
  for (const auto& t : all) floor_texels += t.normal.y > 0.9f && t.centre.y < 1e-3f;
  ASSERT_GT(floor_texels, 0u);
  const float texel_m = std::sqrt(12.0f / float(floor_texels));

  // Bands: floor texels within one texel of each wall, wall texels within one texel of the
  // floor (8 contact lines); the shadowed corner: floor texels along the block's far side
  // (x = 2.5) and the block's far face along the floor.
  std::vector<Texel> texels;
  std::vector<int> band;  // 0..7 contact lines, 8 = shadowed corner
  const auto add = [&](const Texel& t, int which) { texels.push_back(t), band.push_back(which); };
  for (const auto& t : all) {
    const glm::vec3 c = t.centre;
    const bool on_floor = t.normal.y > 0.9f && c.y < 1e-3f;
    if (on_floor) {
      if (c.x < texel_m) add(t, 0);
      else if (c.x > 4.0f - texel_m) add(t, 1);
      else if (c.z < texel_m) add(t, 2);
      else if (c.z > 3.0f - texel_m) add(t, 3);
      else if (c.x > block_hi.x && c.x < block_hi.x + texel_m && c.z > block_lo.z + texel_m &&
               c.z < block_hi.z - texel_m)
        add(t, 8);
      continue;
    }
    if (c.y >= texel_m) continue;
    const bool room_wall = c.x < 1e-3f || c.x > 4.0f - 1e-3f || c.z < 1e-3f || c.z > 3.0f - 1e-3f;
    if (room_wall && c.x > texel_m && c.x < 4.0f - texel_m && c.z > texel_m && c.z < 3.0f - texel_m) continue;
    if (room_wall) {
      if (t.normal.x > 0.9f) add(t, 4);
      else if (t.normal.x < -0.9f) add(t, 5);
      else if (t.normal.z > 0.9f) add(t, 6);
      else if (t.normal.z < -0.9f) add(t, 7);
    } else if (t.normal.x > 0.9f && std::abs(c.x - block_hi.x) < 1e-3f && c.z > block_lo.z + texel_m &&
               c.z < block_hi.z - texel_m) {
      add(t, 8);
    }
  }
  referenceAt(*b, lights, texels);
  if (::testing::Test::HasFatalFailure()) return;

  for (int line = 0; line < 8; ++line) {
    double baked = 0.0, ref = 0.0;
    int n = 0;
    for (std::size_t i = 0; i < texels.size(); ++i)
      if (band[i] == line) baked += texels[i].baked, ref += texels[i].reference, ++n;
    ASSERT_GT(n, 0) << "contact line " << line << " has no texels";
    EXPECT_NEAR(baked / ref, 1.0, 0.05) << "contact line " << line << " (" << n << " texels): bias " << baked / ref;
  }
  // The shadowed corners: the block's far side on the floor (band 8), and the far wall's
  // contact with the floor where the block shadows it (z within the block's extent).
  int corner = 0;
  for (std::size_t i = 0; i < texels.size(); ++i) {
    const bool far_contact = (band[i] == 1 || band[i] == 5) && texels[i].centre.z > block_lo.z &&
                             texels[i].centre.z < block_hi.z;
    if (band[i] != 8 && !far_contact) continue;
    ++corner;
    EXPECT_LE(texels[i].baked, 1.5f * texels[i].reference)
        << "shadowed corner texel at (" << texels[i].centre.x << ", " << texels[i].centre.y << ", "
        << texels[i].centre.z << "): " << texels[i].baked / texels[i].reference << "x the reference";
  }
  EXPECT_GT(corner, 0);
}

INSTANTIATE_TEST_SUITE_P(CachePlacement, ClosedRoom, ::testing::Bool(), [](const ::testing::TestParamInfo<bool>& info) {
  return std::string(info.param ? "DoubleSided" : "SingleSided");
});

// Sealed pockets (closed voids between a level's brushes): open-bottomed, inward-facing
// boxes standing on a floor, so every ray from inside meets a front face and passes the
// back-face test, but no light gets in and no one sees in. One, 20 cm wide, covers the centre
// of a 50 cm texel whose rest is in the open: the cache moves to the open part, inside its
// texel. Another encloses a whole small floor chart: its texel is invalid, marked sealed.
TEST(SealedPocket, CachesLeaveClosedVoids) {
  scene::Scene s;
  const auto addPocket = [&](glm::vec3 lo, glm::vec3 hi) {
    const std::size_t before = s.meshes.size();
    addBox(s, lo, hi, /*inward=*/true);
    s.meshes.erase(s.meshes.begin() + std::ptrdiff_t(before + 2));  // its bottom (y = lo): the floor closes it
  };
  // Floor 2 x 2 m on the first 4 x 4 texels of an 8 x 8 atlas: x = -1 + 4u, z = -1 + 4v.
  addQuad(s, {-1, 0, -1}, {-1, 0, 1}, {1, 0, 1}, {1, 0, -1});
  s.meshes.back().uv1 = {{0.0f, 0.0f}, {0.0f, 0.5f}, {0.5f, 0.5f}, {0.5f, 0.0f}};
  constexpr int kRes = 8;
  const glm::vec3 centre(-0.25f, 0.0f, -0.25f);  // texel (1, 1)
  constexpr float kHalf = 0.1f, kHeight = 0.1f;
  addPocket(centre - glm::vec3(kHalf, 0, kHalf), centre + glm::vec3(kHalf, kHeight, kHalf));
  // A 30 cm floor chart in the middle of texel (5, 5) (75 cm texels), wholly in a pocket.
  addQuad(s, {2.85f, 0, 2.85f}, {2.85f, 0, 3.15f}, {3.15f, 0, 3.15f}, {3.15f, 0, 2.85f});
  constexpr float kLo = 5.3f / kRes, kHi = 5.7f / kRes;
  s.meshes.back().uv1 = {{kLo, kLo}, {kLo, kHi}, {kHi, kHi}, {kHi, kLo}};
  addPocket({2.85f, 0, 2.85f}, {3.15f, kHeight, 3.15f});
  relight::testing::finish(s);
  auto accel = rt::Accel::build(s);
  ASSERT_TRUE(accel) << accel.status().toString();
  auto caches = placeLightmapCaches(s, *accel, {.resolution = kRes, .validity = {.rays = 64}});
  ASSERT_TRUE(caches) << caches.status().toString();

  int checked = 0;
  for (std::size_t c = 0; c < caches->size(); ++c) {
    const std::uint32_t t = caches->texel[c];
    const glm::vec3 p = caches->position[c];
    if (t == 1 * kRes + 1) {
      ++checked;
      EXPECT_TRUE(caches->valid[c]);
      EXPECT_EQ(caches->pushed[c], 1);
      EXPECT_TRUE(std::abs(p.x - centre.x) > kHalf || std::abs(p.z - centre.z) > kHalf)
          << "the cache stayed in the sealed pocket at " << p.x << ", " << p.z;
      EXPECT_TRUE(p.x >= -0.5f && p.x <= 0.0f && p.z >= -0.5f && p.z <= 0.0f)
          << "the cache left its texel: " << p.x << ", " << p.z;
    } else if (t == 5 * kRes + 5) {
      ++checked;
      EXPECT_FALSE(caches->valid[c]) << "a texel wholly in a closed void is valid";
      EXPECT_EQ(caches->pushed[c], 2);
    } else {
      EXPECT_TRUE(caches->valid[c]);
      EXPECT_FALSE(caches->pushed[c]) << "texel " << t % kRes << ", " << t / kRes << " moved";
    }
  }
  EXPECT_EQ(checked, 2);
}

// A lit card 2 mm above a floor, a point light above: single-sided facing up or down, or
// double-sided. The floor under the card is in the card's shadow and sees only the card's
// underside, so it gets (almost) nothing. A floor cache moved out from under the card reads
// the lit floor; a double-sided card whose underside is owned by its lit top surfels (one
// surfel per place for both sides) passes the top's light through.
enum class Card { kFacingUp, kFacingDown, kDoubleSided };
class CardOverFloor : public ::testing::TestWithParam<Card> {};

TEST_P(CardOverFloor, FloorUnderTheCardStaysDark) {
  const Card card = GetParam();
  scene::Scene s;
  const int grey = addMaterial(s, glm::vec3(0.5f));
  const int two_sided = addMaterial(s, glm::vec3(0.5f), glm::vec3(0.0f), /*double_sided=*/true);
  addQuad(s, {-1.5f, 0, 1.5f}, {1.5f, 0, 1.5f}, {1.5f, 0, -1.5f}, {-1.5f, 0, -1.5f}, grey);
  constexpr float kHalf = 0.4f, kGap = 0.002f;
  if (card == Card::kFacingDown)
    addQuad(s, {-kHalf, kGap, -kHalf}, {kHalf, kGap, -kHalf}, {kHalf, kGap, kHalf}, {-kHalf, kGap, kHalf}, grey);
  else
    addQuad(s, {-kHalf, kGap, kHalf}, {kHalf, kGap, kHalf}, {kHalf, kGap, -kHalf}, {-kHalf, kGap, -kHalf},
            card == Card::kDoubleSided ? two_sided : grey);
  auto b = Baked::make(std::move(s), placementOptions());
  ASSERT_TRUE(b);
  constexpr float kIntensity = 10.0f, kHeight = 1.5f;
  LightSet lights;
  ASSERT_TRUE(lights.add(pointLight({0.0f, kHeight, 0.0f}, kIntensity)));
  const std::vector<Texel> all = bakeTexels(*b, lights);
  ASSERT_FALSE(all.empty());
  // The lit side's irradiance at the card's centre (the light straight above it).
  const float lit = kIntensity / ((kHeight - kGap) * (kHeight - kGap));
  std::size_t floor_texels = 0;
  for (const auto& t : all) floor_texels += t.normal.y > 0.9f && t.centre.y < 1e-3f;
  const float texel_m = std::sqrt(9.0f / float(std::max<std::size_t>(floor_texels, 1)));
  int under = 0;
  float worst = 0.0f;
  for (const auto& t : all) {
    const glm::vec3 c = t.centre;
    if (!(t.normal.y > 0.9f && c.y < 1e-3f)) continue;
    if (std::abs(c.x) > kHalf - texel_m || std::abs(c.z) > kHalf - texel_m) continue;
    ++under;
    worst = std::max(worst, t.baked / lit);
  }
  ASSERT_GT(under, 0);
  EXPECT_LE(worst, 0.02f) << under << " floor texels under the card; the brightest gets " << worst
                          << " of the lit side's irradiance";
}

INSTANTIATE_TEST_SUITE_P(Sides, CardOverFloor, ::testing::Values(Card::kFacingUp, Card::kFacingDown, Card::kDoubleSided),
                         [](const ::testing::TestParamInfo<Card>& info) {
                           return std::string(info.param == Card::kFacingUp     ? "SingleSidedFacingUp"
                                              : info.param == Card::kFacingDown ? "SingleSidedFacingDown"
                                                                                : "DoubleSided");
                         });

}  // namespace
}  // namespace lightlink::caches
