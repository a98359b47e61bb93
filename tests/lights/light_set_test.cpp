#include "core/lights/light_set.h"

#include <cmath>
#include <limits>

#include <gtest/gtest.h>

#include "tests/common/testing.h"

namespace lightlink::lights {
namespace {

using nlohmann::json;

LightEntry point(std::string id, float intensity) {
  LightEntry e;
  e.id = std::move(id);
  e.light.kind = Light::Kind::kPoint;
  e.light.intensity = intensity;
  return e;
}

std::string errorOf(const json& j) {
  auto s = LightSet::fromJson(j);
  EXPECT_FALSE(s) << j.dump();
  return s ? std::string() : s.status().message();
}

TEST(LightSet, FromSceneGivesStableIdsAllBaked) {
  struct {
    std::vector<Light> lights;
  } s;  // a scene's lights
  Light a;
  a.name = "sun";
  a.kind = Light::Kind::kDirectional;
  Light b;  // unnamed
  Light c;
  c.name = "sun";  // duplicate name
  s.lights = {a, b, c};
  const LightSet set = LightSet::fromSceneLights(s.lights);
  ASSERT_EQ(set.lights().size(), 3u);
  EXPECT_EQ(set.lights()[0].id, "light0");  // "sun" is not unique
  EXPECT_EQ(set.lights()[1].id, "light1");
  EXPECT_EQ(set.lights()[2].id, "light2");
  for (const auto& e : set.lights()) EXPECT_TRUE(e.baked);
  s.lights = {a, b};
  EXPECT_EQ(LightSet::fromSceneLights(s.lights).lights()[0].id, "sun");
}

TEST(LightSet, EditsValidateAndBumpTheVersion) {
  LightSet set;
  EXPECT_EQ(set.version(), 0u);
  ASSERT_TRUE(set.add(point("a", 10.0f)));
  EXPECT_EQ(set.version(), 1u);
  Status dup = set.add(point("a", 1.0f));
  EXPECT_FALSE(dup);
  EXPECT_NE(dup.message().find("duplicate"), std::string::npos);
  EXPECT_EQ(set.version(), 1u);  // failed edits change nothing
  Status neg = set.modify(point("a", -1.0f));
  ASSERT_FALSE(neg);
  EXPECT_EQ(neg.message(), "lights[\"a\"].intensity: -1 is negative");
  EXPECT_FALSE(set.modify(point("a", std::numeric_limits<float>::quiet_NaN())));
  EXPECT_FALSE(set.modify(point("a", std::numeric_limits<float>::infinity())));
  Status huge = set.modify(point("a", 1e13f));
  ASSERT_FALSE(huge);
  EXPECT_NE(huge.message().find("exceeds"), std::string::npos);
  EXPECT_FALSE(set.remove("nope"));
  EXPECT_FALSE(set.modify(point("nope", 1.0f)));
  ASSERT_TRUE(set.modify(point("a", 0.0f)));  // zero power is allowed
  EXPECT_EQ(set.version(), 2u);
  ASSERT_TRUE(set.remove("a"));
  EXPECT_EQ(set.version(), 3u);
  EXPECT_TRUE(set.lights().empty());
  LightEntry spot = point("s", 1.0f);
  spot.light.kind = Light::Kind::kSpot;
  spot.light.inner_cone_angle = 0.8f;
  spot.light.outer_cone_angle = 0.5f;
  Status cone = set.add(spot);
  ASSERT_FALSE(cone);
  EXPECT_NE(cone.message().find("inner_cone_angle"), std::string::npos);
}

TEST(LightSet, JsonRoundTrip) {
  LightSet set;
  LightEntry sun;
  sun.id = "sun";
  sun.light.kind = Light::Kind::kDirectional;
  sun.light.direction = glm::vec3(0, -2, 0);  // stored normalised
  sun.light.intensity = 1000.0f;
  sun.baked = false;
  ASSERT_TRUE(set.add(sun));
  LightEntry spot = point("spot", 50.0f);
  spot.light.kind = Light::Kind::kSpot;
  spot.light.position = {1, 2, 3};
  spot.light.direction = {0, 0, -1};
  spot.light.range = 10.0f;
  spot.light.color = {1, 0.5f, 0.25f};
  ASSERT_TRUE(set.add(spot));
  Sky sky;
  sky.radiance = {0.1f, 0.2f, 0.3f};
  ASSERT_TRUE(set.setSky(sky));
  ASSERT_TRUE(set.setEmissive({.material = 2, .mode = EmissiveOverride::Mode::kRadiance, .value = {5, 5, 5}}));
  EXPECT_EQ(set.find("sun")->light.direction, glm::vec3(0, -1, 0));

  testing::TempDir dir;
  const std::string path = (dir / "lights.json").string();
  ASSERT_TRUE(set.save(path));
  auto back = LightSet::load(path);
  ASSERT_TRUE(back) << back.status().toString();
  ASSERT_EQ(back->lights().size(), 2u);
  for (std::size_t i = 0; i < 2; ++i) {
    EXPECT_EQ(back->lights()[i].id, set.lights()[i].id);
    EXPECT_TRUE(sameLight(back->lights()[i].light, set.lights()[i].light)) << i;
    EXPECT_EQ(back->lights()[i].baked, set.lights()[i].baked);
  }
  EXPECT_EQ(back->sky().radiance, sky.radiance);
  ASSERT_EQ(back->emissive().size(), 1u);
  EXPECT_EQ(back->emissive()[0].material, 2);
  EXPECT_EQ(back->emissive()[0].mode, EmissiveOverride::Mode::kRadiance);
  EXPECT_EQ(back->toJson().dump(), set.toJson().dump());
}

TEST(LightSet, ApplyOverridesByIdAddsAndRemoves) {
  LightSet set;
  ASSERT_TRUE(set.add(point("a", 10.0f)));
  ASSERT_TRUE(set.add(point("b", 20.0f)));
  const auto v = set.version();
  ASSERT_TRUE(set.apply(json::parse(R"({"version": 1, "lights": [
      {"id": "a", "intensity": 15},
      {"id": "b", "remove": true},
      {"id": "sun", "type": "directional", "direction": [0, -1, 0], "intensity": 800, "baked": false}]})")));
  EXPECT_GT(set.version(), v);
  ASSERT_EQ(set.lights().size(), 2u);
  EXPECT_EQ(set.find("a")->light.intensity, 15.0f);
  EXPECT_EQ(set.find("a")->light.kind, Light::Kind::kPoint);  // untouched fields kept
  EXPECT_EQ(set.find("b"), nullptr);
  EXPECT_FALSE(set.find("sun")->baked);
  // All or nothing: an error in the second light leaves the first unchanged.
  const auto before = set.toJson().dump();
  EXPECT_FALSE(set.apply(json::parse(R"({"version": 1, "lights": [
      {"id": "a", "intensity": 1}, {"id": "sun", "intensity": -5}]})")));
  EXPECT_EQ(set.toJson().dump(), before);
}

TEST(LightSet, BadJsonIsRejectedNamingTheField) {
  EXPECT_EQ(errorOf(json::parse(R"({"version": 1, "lights": [
      {"id": "a", "type": "point", "intensity": 1},
      {"id": "b", "type": "point", "intensity": 1},
      {"id": "c", "type": "point", "intensity": -1}]})")),
            "lights[2].intensity: -1 is negative");
  EXPECT_NE(errorOf(json::parse(R"({"version": 1, "lights": [{"id": "a", "type": "point", "intensity": "x"}]})"))
                .find("lights[0].intensity: expected a number"),
            std::string::npos);
  EXPECT_NE(errorOf(json::parse(R"({"version": 1, "lights": [{"id": "a", "type": "point", "color": [1, 2]}]})"))
                .find("lights[0].color"),
            std::string::npos);
  EXPECT_NE(errorOf(json::parse(R"({"version": 1, "lights": [{"id": "a", "type": "laser"}]})")).find("lights[0].type"),
            std::string::npos);
  EXPECT_NE(errorOf(json::parse(R"({"version": 1, "lights": [{"id": "a", "type": "point", "intensity": 1e13}]})"))
                .find("lights[0].intensity"),
            std::string::npos);
  EXPECT_NE(errorOf(json::parse(R"({"version": 1, "lights": [{"id": "a", "type": "point"}, {"id": "a", "type": "point"}]})"))
                .find("lights[1].id: duplicate"),
            std::string::npos);
  EXPECT_NE(errorOf(json::parse(R"({"version": 1, "lights": [{"id": "a", "type": "point", "colour": [1,1,1]}]})"))
                .find("lights[0].colour: unknown field"),
            std::string::npos);
  EXPECT_NE(errorOf(json::parse(R"({"version": 1, "lights": [{"id": "a", "intensity": 1}]})")).find("lights[0].type: missing"),
            std::string::npos);
  EXPECT_NE(errorOf(json::parse(R"({"version": 2})")).find("version"), std::string::npos);
  EXPECT_NE(errorOf(json::parse(R"({"lights": []})")).find("version: missing"), std::string::npos);
  EXPECT_NE(errorOf(json::parse(R"({"version": 1, "sky": {"radiance": [1, -1, 0]}})")).find("sky.radiance[1]"),
            std::string::npos);
  EXPECT_NE(errorOf(json::parse(R"({"version": 1, "sky": {"sh": [[1,1,1]]}})")).find("sky.sh"), std::string::npos);
  EXPECT_NE(errorOf(json::parse(R"({"version": 1, "emissive": [{"material": 0, "scale": 1, "radiance": 1}]})"))
                .find("emissive[0]"),
            std::string::npos);
  EXPECT_NE(errorOf(json::parse(R"({"version": 1, "emissive": [{"material": -3, "scale": 1}]})"))
                .find("emissive[0].material"),
            std::string::npos);
  testing::TempDir dir;
  const std::string path = testing::writeFile(dir / "bad.json", "{\"version\": 1, \"lights\": [");
  auto bad = LightSet::load(path);
  ASSERT_FALSE(bad);
  EXPECT_NE(bad.status().message().find("not valid JSON"), std::string::npos);
}

}  // namespace
}  // namespace lightlink::lights

namespace lightlink::lights {
namespace {

// Found by fuzz_requests (regressions/requests/spot_direction_1e25.bin): a direction of 1e25
// had a float length of infinity and normalised to zero, so an accepted update failed in the
// relight. Lengths are taken in double: huge and tiny non-zero directions become unit vectors.
TEST(LightSet, HugeAndTinyDirectionsNormaliseToUnitVectors) {
  for (const float scale : {1.7e25f, 1e30f, 1e-3f}) {
    LightSet set;
    LightEntry e;
    e.id = "spot";
    e.light.kind = Light::Kind::kSpot;
    e.light.intensity = 1.0f;
    e.light.outer_cone_angle = 0.5f;
    e.light.direction = glm::vec3(0.0f, scale, 0.0f);
    ASSERT_TRUE(set.add(e)) << scale;
    EXPECT_EQ(set.lights()[0].light.direction, glm::vec3(0.0f, 1.0f, 0.0f)) << scale;
    EXPECT_TRUE(LightSet::validate(set.lights()[0], "lights[0]")) << scale;
  }
}

}  // namespace
}  // namespace lightlink::lights
