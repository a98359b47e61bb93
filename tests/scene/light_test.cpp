// KHR_lights_punctual: loading (units, placement by node transforms) and irradianceFrom
// against hand-computed values from the glTF spec's formulas.
#include <cmath>

#include <gtest/gtest.h>

#include "core/scene/light_eval.h"
#include "core/scene/load.h"
#include "tests/common/testing.h"
#include "tests/scene/gltf_builder.h"

namespace lightlink::scene {
namespace {

using testing::GltfBuilder;
using testing::TempDir;

void expectNear(glm::vec3 actual, glm::vec3 expected, float tol = 1e-5f) {
  EXPECT_NEAR(actual.x, expected.x, tol) << "x";
  EXPECT_NEAR(actual.y, expected.y, tol) << "y";
  EXPECT_NEAR(actual.z, expected.z, tol) << "z";
}

Light pointLight(float intensity_cd, glm::vec3 position) {
  Light l;
  l.kind = Light::Kind::kPoint;
  l.intensity = intensity_cd;
  l.position = position;
  return l;
}

TEST(LightEval, PointInverseSquareAndCosine) {
  const Light l = pointLight(4.0f, {0, 0, 2});
  // 4 cd at 2 m, normal incidence: 4 / 2^2 = 1 lux.
  expectNear(irradianceFrom(l, {0, 0, 0}, {0, 0, 1}), glm::vec3(1.0f));
  // Tilted normal, 60 degrees: cos = 0.5.
  const float s = std::sqrt(3.0f) / 2.0f;
  expectNear(irradianceFrom(l, {0, 0, 0}, {s, 0, 0.5f}), glm::vec3(0.5f));
  // Behind the surface: nothing.
  expectNear(irradianceFrom(l, {0, 0, 0}, {0, 0, -1}), glm::vec3(0.0f));
  // Colour scales per channel.
  Light coloured = l;
  coloured.color = {1.0f, 0.5f, 0.25f};
  expectNear(irradianceFrom(coloured, {0, 0, 0}, {0, 0, 1}), {1.0f, 0.5f, 0.25f});
  // On the light itself: 0, not Inf.
  expectNear(irradianceFrom(l, {0, 0, 2}, {0, 0, 1}), glm::vec3(0.0f));
}

TEST(LightEval, RangeWindow) {
  Light l = pointLight(4.0f, {0, 0, 2});
  l.range = 4.0f;
  // d / range = 0.5: (1 - 0.5^4)^2 = (15/16)^2.
  expectNear(irradianceFrom(l, {0, 0, 0}, {0, 0, 1}), glm::vec3(225.0f / 256.0f));
  l.range = 2.0f;  // exactly at range
  expectNear(irradianceFrom(l, {0, 0, 0}, {0, 0, 1}), glm::vec3(0.0f));
  l.range = 1.0f;  // beyond
  expectNear(irradianceFrom(l, {0, 0, 0}, {0, 0, 1}), glm::vec3(0.0f));
  EXPECT_FLOAT_EQ(rangeWindow(l, 0.0f), 1.0f);
  l.range = 0.0f;  // glTF: undefined range = infinite
  EXPECT_FLOAT_EQ(rangeWindow(l, 1e6f), 1.0f);
}

TEST(LightEval, SpotFalloffInsideBetweenAndOutsideCones) {
  Light l;
  l.kind = Light::Kind::kSpot;
  l.intensity = 4.0f;
  l.position = {0, 0, 2};
  l.direction = {0, 0, -1};
  l.inner_cone_angle = 0.2f;
  l.outer_cone_angle = 0.6f;
  const glm::vec3 up{0, 0, 1};
  // On the axis: full 1 lux.
  expectNear(irradianceFrom(l, {0, 0, 0}, up), glm::vec3(1.0f));
  // At angle a off-axis on the plane z = 0: distance 2/cos(a), cos(theta) = cos(a).
  const auto at = [&](float a) {
    const glm::vec3 p{2.0f * std::tan(a), 0.0f, 0.0f};
    const float d2 = glm::dot(p - l.position, p - l.position);
    return std::pair<glm::vec3, float>{p, 4.0f * std::cos(a) / d2};
  };
  {  // inside the inner cone: unattenuated
    auto [p, e] = at(0.15f);
    expectNear(irradianceFrom(l, p, up), glm::vec3(e));
  }
  {  // between the cones: t^2
    const float a = 0.4f;
    auto [p, e] = at(a);
    const float t = (std::cos(a) - std::cos(0.6f)) / (std::cos(0.2f) - std::cos(0.6f));
    expectNear(irradianceFrom(l, p, up), glm::vec3(e * t * t));
    EXPECT_GT(t, 0.0f);
    EXPECT_LT(t, 1.0f);
  }
  {  // outside the outer cone: dark
    auto [p, e] = at(0.7f);
    EXPECT_GT(e, 0.0f);
    expectNear(irradianceFrom(l, p, up), glm::vec3(0.0f));
  }
}

TEST(LightEval, DirectionalIsIlluminanceTimesCosine) {
  Light l;
  l.kind = Light::Kind::kDirectional;
  l.intensity = 10.0f;  // lux
  l.direction = glm::normalize(glm::vec3(0, -1, -1));
  expectNear(irradianceFrom(l, {100, 5, -3}, {0, 0, 1}), glm::vec3(10.0f / std::sqrt(2.0f)));
  expectNear(irradianceFrom(l, {0, 0, 0}, {0, 0, -1}), glm::vec3(0.0f));
}

TEST(LightLoad, KindsUnitsAndPlacementFromNodes) {
  TempDir dir;
  GltfBuilder b;
  b.addNode({{"mesh", b.addTriangles(testing::unitTriangle(), {0, 1, 2})}});
  b.json()["extensionsUsed"] = {"KHR_lights_punctual"};
  b.json()["extensions"] = {{"KHR_lights_punctual",
                             {{"lights",
                               {{{"type", "point"}, {"name", "Bulb"}, {"intensity", 15}, {"color", {1, 0.5, 0.25}}},
                                {{"type", "spot"}, {"intensity", 1000}, {"range", 25},
                                 {"spot", {{"innerConeAngle", 0.35}, {"outerConeAngle", 0.39}}}},
                                {{"type", "directional"}, {"intensity", 10}}}}}}};
  const float s = std::sqrt(0.5f);
  const auto lamp = [](int i) { return nlohmann::json{{"KHR_lights_punctual", {{"light", i}}}}; };
  const int parent = b.addNode({{"translation", {10, 0, 0}}});
  const int bulb = b.addNode({{"translation", {0, 2, 0}}, {"extensions", lamp(0)}}, false);
  b.addChild(parent, bulb);
  // Rotated -90 degrees about X: -Z (forward) becomes -Y (down); scaled 3x, still unit.
  b.addNode({{"translation", {1, 5, 1}}, {"rotation", {-s, 0, 0, s}}, {"scale", {3, 3, 3}}, {"extensions", lamp(1)}});
  b.addNode({{"extensions", lamp(2)}});
  b.addNode({{"extensions", lamp(0)}, {"translation", {0, 0, 9}}});  // one light, two nodes
  Expected<Scene> scene = loadGltf(b.writeGltf(dir / "t.gltf"));
  ASSERT_TRUE(scene.hasValue()) << scene.status().toString();
  ASSERT_EQ(scene->lights.size(), 4u);
  const Light& point = scene->lights[0];
  EXPECT_EQ(point.kind, Light::Kind::kPoint);
  EXPECT_EQ(point.name, "Bulb");
  EXPECT_EQ(point.gltf_node, bulb);
  EXPECT_FLOAT_EQ(point.intensity, 15.0f);
  expectNear(point.color, {1, 0.5f, 0.25f});
  expectNear(point.position, {10, 2, 0});
  EXPECT_EQ(point.range, 0.0f);
  const Light& spot = scene->lights[1];
  EXPECT_EQ(spot.kind, Light::Kind::kSpot);
  EXPECT_EQ(spot.name, "light 1");
  EXPECT_FLOAT_EQ(spot.intensity, 1000.0f);
  EXPECT_FLOAT_EQ(spot.range, 25.0f);
  EXPECT_FLOAT_EQ(spot.inner_cone_angle, 0.35f);
  EXPECT_FLOAT_EQ(spot.outer_cone_angle, 0.39f);
  expectNear(spot.position, {1, 5, 1});
  expectNear(spot.direction, {0, -1, 0});
  const Light& sun = scene->lights[2];
  EXPECT_EQ(sun.kind, Light::Kind::kDirectional);
  expectNear(sun.direction, {0, 0, -1});
  EXPECT_FLOAT_EQ(sun.intensity, 10.0f);
  expectNear(scene->lights[3].position, {0, 0, 9});
  // The directional light straight down -Z onto a +Z facing floor: its illuminance.
  expectNear(irradianceFrom(sun, {0, 0, 0}, {0, 0, 1}), glm::vec3(10.0f));
}

}  // namespace
}  // namespace lightlink::scene
