// Scenario blending rules (core/lights/scenarios.h); tests/relight/scenario_blend_test.cpp
// checks that relighting a blend gives the blend of the relights.
#include <gtest/gtest.h>

#include "core/lights/scenarios.h"

namespace lightlink::lights {
namespace {

LightEntry point(const std::string& id, float intensity) {
  LightEntry e;
  e.id = id;
  e.light.kind = Light::Kind::kPoint;
  e.light.intensity = intensity;
  e.light.position = glm::vec3(1, 2, 3);
  return e;
}

std::vector<Scenario> dayAndNight() {
  Scenario day{"day", {}}, night{"night", {}};
  EXPECT_TRUE(day.lights.add(point("sun", 100.0f)));
  EXPECT_TRUE(day.lights.setSky(Sky{glm::vec3(2.0f), std::nullopt}));
  EXPECT_TRUE(day.lights.setEmissive({0, EmissiveOverride::Mode::kScale, glm::vec3(0.0f)}));
  EXPECT_TRUE(night.lights.add(point("lamp", 10.0f)));
  EXPECT_TRUE(night.lights.add(point("sun", 1.0f)));
  EXPECT_TRUE(night.lights.setEmissive({0, EmissiveOverride::Mode::kScale, glm::vec3(2.0f)}));
  return {day, night};
}

const std::vector<MaterialEmission> kMaterials = {{glm::vec3(5.0f), true}, {glm::vec3(0.0f), false}};

TEST(Scenarios, OneScenarioKeepsItsIdsAndScalesItsLights) {
  const auto s = dayAndNight();
  auto b = blendScenarios(s, std::vector<ScenarioWeight>{{"night", 0.5f}}, kMaterials);
  ASSERT_TRUE(b) << b.status().toString();
  ASSERT_EQ(b->lights().size(), 2u);
  EXPECT_EQ(b->lights()[0].id, "lamp");
  EXPECT_FLOAT_EQ(b->lights()[0].light.intensity, 5.0f);
  EXPECT_TRUE(b->emissive().empty()) << "0.5 x scale 2 is the material's own emission: no override";
  EXPECT_EQ(b->sky().radiance, glm::vec3(0.0f));
}

TEST(Scenarios, SeveralScenariosPrefixIdsAndSumEmissionAndSky) {
  const auto s = dayAndNight();
  auto b = blendScenarios(s, std::vector<ScenarioWeight>{{"day", 0.25f}, {"night", 0.75f}}, kMaterials);
  ASSERT_TRUE(b) << b.status().toString();
  ASSERT_EQ(b->lights().size(), 3u);
  EXPECT_EQ(b->lights()[0].id, "day/sun");
  EXPECT_FLOAT_EQ(b->lights()[0].light.intensity, 25.0f);
  EXPECT_EQ(b->lights()[2].id, "night/sun");
  EXPECT_FLOAT_EQ(b->lights()[2].light.intensity, 0.75f);
  ASSERT_EQ(b->emissive().size(), 1u);
  EXPECT_EQ(b->emissive()[0].mode, EmissiveOverride::Mode::kScale);
  EXPECT_EQ(b->emissive()[0].value, glm::vec3(1.5f));  // 0.25 * 0 + 0.75 * 2
  EXPECT_EQ(b->sky().radiance, glm::vec3(0.5f));
}

TEST(Scenarios, WeightsThatDoNotSumToOneScaleUnoverriddenEmitters) {
  Scenario a{"a", {}};
  auto b = blendScenarios(std::vector<Scenario>{a}, std::vector<ScenarioWeight>{{"a", 0.5f}}, kMaterials);
  ASSERT_TRUE(b);
  ASSERT_EQ(b->emissive().size(), 1u);  // material 0 emits; material 1 does not and stays untouched
  EXPECT_EQ(b->emissive()[0].value, glm::vec3(0.5f));
  auto off = blendScenarios(std::vector<Scenario>{a}, std::vector<ScenarioWeight>{{"a", 0.0f}}, kMaterials);
  ASSERT_TRUE(off);
  EXPECT_TRUE(off->lights().empty());
  ASSERT_EQ(off->emissive().size(), 1u);
  EXPECT_EQ(off->emissive()[0].value, glm::vec3(0.0f));
}

TEST(Scenarios, ConstantRadianceBlendsWithAnUntexturedEmissionOnly) {
  Scenario a{"a", {}}, c{"c", {}};
  ASSERT_TRUE(c.lights.setEmissive({0, EmissiveOverride::Mode::kRadiance, glm::vec3(4.0f)}));
  ASSERT_TRUE(c.lights.setEmissive({1, EmissiveOverride::Mode::kRadiance, glm::vec3(4.0f)}));
  const std::vector<Scenario> s{a, c};
  const std::vector<ScenarioWeight> w{{"a", 0.5f}, {"c", 0.5f}};
  auto textured = blendScenarios(s, w, kMaterials);
  ASSERT_FALSE(textured);
  EXPECT_NE(textured.status().message().find("emissive[material 0]"), std::string::npos) << textured.status().message();
  const std::vector<MaterialEmission> plain = {{glm::vec3(5.0f), false}, {glm::vec3(0.0f), false}};
  auto b = blendScenarios(s, w, plain);
  ASSERT_TRUE(b) << b.status().toString();
  ASSERT_EQ(b->emissive().size(), 2u);
  EXPECT_EQ(b->emissive()[0].mode, EmissiveOverride::Mode::kRadiance);
  EXPECT_EQ(b->emissive()[0].value, glm::vec3(4.5f));  // 0.5 * 5 + 0.5 * 4
  EXPECT_EQ(b->emissive()[1].value, glm::vec3(2.0f));
}

TEST(Scenarios, SkyShBlendsAsSh) {
  Scenario a{"a", {}}, b{"b", {}};
  ASSERT_TRUE(a.lights.setSky(Sky{glm::vec3(1.0f), std::nullopt}));
  std::array<glm::vec3, 9> sh{};
  sh[1] = glm::vec3(2.0f);
  ASSERT_TRUE(b.lights.setSky(Sky{glm::vec3(0.0f), sh}));
  auto m = blendScenarios(std::vector<Scenario>{a, b}, std::vector<ScenarioWeight>{{"a", 1.0f}, {"b", 0.5f}}, {});
  ASSERT_TRUE(m) << m.status().toString();
  ASSERT_TRUE(m->sky().sh.has_value());
  EXPECT_FLOAT_EQ((*m->sky().sh)[0].x, a.lights.sky().radianceSh()[0].x);
  EXPECT_FLOAT_EQ((*m->sky().sh)[1].x, 1.0f);
}

TEST(Scenarios, BadBlendsNameWhatIsWrong) {
  const auto s = dayAndNight();
  const auto message = [&](std::vector<ScenarioWeight> w) {
    auto b = blendScenarios(s, w, kMaterials);
    EXPECT_FALSE(b);
    return b ? std::string() : b.status().message();
  };
  EXPECT_NE(message({}).find("no scenario"), std::string::npos);
  EXPECT_NE(message({{"dusk", 1.0f}}).find("\"dusk\": no such scenario"), std::string::npos);
  EXPECT_NE(message({{"day", 1.0f}, {"day", 1.0f}}).find("named twice"), std::string::npos);
  EXPECT_NE(message({{"day", -1.0f}}).find("outside"), std::string::npos);
  EXPECT_NE(message({{"day", std::nanf("")}}).find("outside"), std::string::npos);
  EXPECT_NE(message({{"a/../etc", 1.0f}}).find("only letters"), std::string::npos);
  Scenario unbaked{"unbaked", {}};
  ASSERT_TRUE(unbaked.lights.setEmissiveBaked(false));
  auto mixed = blendScenarios(std::vector<Scenario>{s[0], unbaked},
                              std::vector<ScenarioWeight>{{"day", 1.0f}, {"unbaked", 1.0f}}, kMaterials);
  ASSERT_FALSE(mixed);
  EXPECT_NE(mixed.status().message().find("emissive_baked differs"), std::string::npos);
  Scenario bad_material{"bad", {}};
  ASSERT_TRUE(bad_material.lights.setEmissive({7, EmissiveOverride::Mode::kScale, glm::vec3(1.0f)}));
  auto unknown = blendScenarios(std::vector<Scenario>{bad_material}, std::vector<ScenarioWeight>{{"bad", 1.0f}},
                                kMaterials);
  ASSERT_FALSE(unknown);
  EXPECT_NE(unknown.status().message().find("scenario \"bad\""), std::string::npos);
}

TEST(Scenarios, NamesAndWeightsParse) {
  auto w = parseScenarioWeight("night=0.25");
  ASSERT_TRUE(w);
  EXPECT_EQ(w->name, "night");
  EXPECT_FLOAT_EQ(w->weight, 0.25f);
  auto bare = parseScenarioWeight("day");
  ASSERT_TRUE(bare);
  EXPECT_FLOAT_EQ(bare->weight, 1.0f);
  EXPECT_FALSE(parseScenarioWeight("day=0.5x"));
  EXPECT_FALSE(parseScenarioWeight("day="));
  EXPECT_FALSE(parseScenarioWeight("=1"));
  EXPECT_FALSE(parseScenarioWeight("a/b=1"));
  EXPECT_FALSE(parseScenarioWeight(".hidden"));
  EXPECT_FALSE(parseScenarioWeight("day=1e9"));
  EXPECT_TRUE(validateScenarioName("door-open_2.v1"));
  EXPECT_FALSE(validateScenarioName(std::string(65, 'a')));
}

}  // namespace
}  // namespace lightlink::lights
