// Typed light updates and light-set JSON -> UpdateLightsRequest: what goes where, and errors
// that name the field.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "clients/client/light_update.h"
#include "proto/lightlink.pb.h"

namespace lightlink::client {
namespace {

void expectError(const Status& s, const std::string& fragment) {
  ASSERT_FALSE(s) << "expected an error containing '" << fragment << "'";
  EXPECT_EQ(s.code(), Code::kInvalidInput);
  EXPECT_NE(s.message().find(fragment), std::string::npos) << "message: " << s.message();
}

TEST(ClientLightUpdate, TypedCallsFillTheRequest) {
  LightUpdate u;
  LightFields lamp;
  lamp.id = "lamp";
  lamp.type = LightType::kSpot;
  lamp.position = Vec3{1, 2, 3};
  lamp.direction = Vec3{0, -1, 0};
  lamp.intensity = 40.0f;
  lamp.inner_cone_angle = 0.2f;
  lamp.outer_cone_angle = 0.5f;
  ASSERT_TRUE(u.add(lamp));
  LightFields moved;
  moved.id = "light0";
  moved.position = Vec3{0.5f, 1.0f, 0.0f};
  ASSERT_TRUE(u.modify(moved));
  ASSERT_TRUE(u.remove("old"));
  ASSERT_TRUE(u.sky(Vec3{0.1f, 0.2f, 0.3f}));
  ASSERT_TRUE(u.emissiveScale(2, Vec3{2, 2, 2}));
  u.emissiveBaked(false);
  const auto& r = u.proto();
  ASSERT_EQ(r.add_size(), 1);
  EXPECT_EQ(r.add(0).type(), v1::LIGHT_TYPE_SPOT);
  EXPECT_EQ(r.add(0).position().z(), 3.0f);
  EXPECT_FALSE(r.add(0).has_color());  // unset: the daemon's default
  ASSERT_EQ(r.modify_size(), 1);
  EXPECT_TRUE(r.modify(0).has_position());
  EXPECT_FALSE(r.modify(0).has_intensity());  // modify: only the fields given change
  EXPECT_EQ(r.modify(0).type(), v1::LIGHT_TYPE_UNSPECIFIED);
  EXPECT_EQ(r.remove(0), "old");
  EXPECT_EQ(r.sky().radiance().y(), 0.2f);
  EXPECT_EQ(r.emissive(0).material(), 2);
  EXPECT_TRUE(r.emissive(0).has_scale());
  EXPECT_TRUE(r.has_emissive_baked() && !r.emissive_baked());

  std::set<std::string> ids = {"light0", "old"};
  u.applyToIds(ids);
  EXPECT_EQ(ids, (std::set<std::string>{"lamp", "light0"}));
}

TEST(ClientLightUpdate, TypedErrorsNameTheField) {
  LightUpdate u;
  LightFields l;
  l.id = "a";
  l.type = LightType::kPoint;
  l.intensity = std::numeric_limits<float>::quiet_NaN();
  expectError(u.add(l), "add[0].intensity: nan is not finite");
  l.intensity = -1.0f;
  expectError(u.add(l), "add[0].intensity: -1 is negative");
  l.intensity = 1.0f;
  l.color = Vec3{1, -0.5f, 1};
  expectError(u.add(l), "add[0].color[1]: -0.5 is negative");
  l.color.reset();
  l.direction = Vec3{0, 0, 0};
  expectError(u.add(l), "add[0].direction: must be a non-zero vector");
  l.direction.reset();
  l.inner_cone_angle = 0.6f;
  l.outer_cone_angle = 0.4f;
  expectError(u.add(l), "add[0].inner_cone_angle");
  l.inner_cone_angle.reset();
  l.outer_cone_angle.reset();
  LightFields untyped;
  untyped.id = "b";
  expectError(u.add(untyped), "add[0].type: missing for new light");
  ASSERT_TRUE(u.add(l));
  expectError(u.add(l), "add[1].id: duplicate id \"a\"");
  LightFields empty_id;
  expectError(u.modify(empty_id), "modify[0].id: must not be empty");
  expectError(u.sky(Vec3{0, 0, 0}, std::vector<Vec3>(4)), "sky.sh: 4 coefficients");
  expectError(u.emissiveScale(-1, Vec3{1, 1, 1}), "emissive[0].material: -1 is not a material index");
  EXPECT_EQ(u.proto().add_size(), 1);  // failed calls changed nothing
}

TEST(ClientLightUpdate, ReplaceLightsIsAllOrNothing) {
  LightUpdate u;
  LightFields a;
  a.id = "a";
  a.type = LightType::kDirectional;
  a.direction = Vec3{0, -1, 0};
  LightFields bad = a;
  bad.id = "b";
  bad.intensity = std::numeric_limits<float>::infinity();
  expectError(u.replaceLights({a, bad}), "add[1].intensity");
  EXPECT_FALSE(u.proto().replace_lights());
  EXPECT_TRUE(u.empty());
  ASSERT_TRUE(u.replaceLights({a}));
  EXPECT_TRUE(u.proto().replace_lights());
  std::set<std::string> ids = {"x", "y"};
  u.applyToIds(ids);
  EXPECT_EQ(ids, std::set<std::string>{"a"});
}

TEST(ClientLightSetJson, MergesIntoAddModifyRemove) {
  const std::set<std::string> known = {"light0", "ceiling"};
  auto u = LightUpdate::fromLightSetText(R"({
    "version": 1,
    "lights": [
      {"id": "light0", "position": [0.1, 1.5, 0.2], "intensity": 12},
      {"id": "lamp", "type": "point", "position": [2, 2.5, 0], "intensity": 120, "range": 8},
      {"id": "ceiling", "remove": true}
    ],
    "sky": {"radiance": [0.2, 0.3, 0.5]},
    "emissive": [{"material": 4, "scale": 2.0}, {"material": 7, "radiance": [10, 8, 6]}],
    "emissive_baked": true
  })",
                                         &known);
  ASSERT_TRUE(u) << u.status().toString();
  const auto& r = u->proto();
  ASSERT_EQ(r.modify_size(), 1);
  EXPECT_EQ(r.modify(0).id(), "light0");
  EXPECT_FLOAT_EQ(r.modify(0).position().y(), 1.5f);
  EXPECT_FALSE(r.modify(0).has_color());
  ASSERT_EQ(r.add_size(), 1);
  EXPECT_EQ(r.add(0).id(), "lamp");
  EXPECT_EQ(r.add(0).type(), v1::LIGHT_TYPE_POINT);
  EXPECT_FLOAT_EQ(r.add(0).range(), 8.0f);
  ASSERT_EQ(r.remove_size(), 1);
  EXPECT_EQ(r.remove(0), "ceiling");
  EXPECT_FLOAT_EQ(r.sky().radiance().z(), 0.5f);
  ASSERT_EQ(r.emissive_size(), 2);
  EXPECT_FLOAT_EQ(r.emissive(0).scale().y(), 2.0f);  // a number means grey
  EXPECT_FLOAT_EQ(r.emissive(1).radiance().x(), 10.0f);
  EXPECT_TRUE(r.emissive_baked());
}

TEST(ClientLightSetJson, WithoutKnownIdsATypedEntryIsAnAdd) {
  auto u = LightUpdate::fromLightSetText(
      R"({"version": 1, "lights": [{"id": "n", "type": "directional", "direction": [0, -1, 0]},
                                    {"id": "light0", "intensity": 3}]})",
      nullptr);
  ASSERT_TRUE(u) << u.status().toString();
  EXPECT_EQ(u->proto().add_size(), 1);
  EXPECT_EQ(u->proto().modify_size(), 1);
}

TEST(ClientLightSetJson, ErrorsNameTheDocumentPath) {
  const std::set<std::string> known = {"light0"};
  auto err = [&](const std::string& text) { return LightUpdate::fromLightSetText(text, &known).status(); };
  expectError(err("{"), "not valid JSON");
  expectError(err(R"({"lights": []})"), "version: missing");
  expectError(err(R"({"version": 2})"), "version: 2 is not supported");
  expectError(err(R"({"version": 1, "colour": 1})"), "colour: unknown field");
  expectError(err(R"({"version": 1, "lights": [{"id": "light0", "colour": [1,1,1]}]})"),
              "lights[0].colour: unknown field");
  expectError(err(R"({"version": 1, "lights": [{"id": "light0", "position": [1, "x", 2]}]})"),
              "lights[0].position[1]: expected a number, got string");
  expectError(err(R"({"version": 1, "lights": [{"id": "light0", "position": [1, 2]}]})"),
              "lights[0].position: expected an array of 3 numbers");
  expectError(err(R"({"version": 1, "lights": [{"id": "light0"}, {"id": "new", "intensity": 1}]})"),
              "lights[1].type: missing for new light \"new\"");
  expectError(err(R"({"version": 1, "lights": [{"id": "light0", "intensity": -4}]})"),
              "lights[0].intensity: -4 is negative");
  expectError(err(R"({"version": 1, "lights": [{"id": "light0", "intensity": 1e300}]})"),
              "lights[0].intensity: 1e+300 is out of float range");
  expectError(err(R"({"version": 1, "lights": [{"id": "light0", "type": "area"}]})"),
              "lights[0].type: \"area\" is not point, spot or directional");
  expectError(err(R"({"version": 1, "lights": [{"id": "light0"}, {"id": "light0"}]})"),
              "lights[1].id: duplicate id \"light0\"");
  expectError(err(R"({"version": 1, "lights": [{"id": "ghost", "remove": true}]})"),
              "lights[0].id: unknown id \"ghost\" cannot be removed");
  expectError(err(R"({"version": 1, "lights": [{"id": "light0", "baked": "yes"}]})"),
              "lights[0].baked: expected true or false, got string");
  expectError(err(R"({"version": 1, "sky": {"radiance": [0, -1, 0]}})"), "sky.radiance[1]: -1 is negative");
  expectError(err(R"({"version": 1, "sky": {"sh": [[0,0,0]]}})"), "sky.sh: expected 9 RGB coefficients");
  expectError(err(R"({"version": 1, "emissive": [{"material": 1, "scale": 1, "radiance": 2}]})"),
              "emissive[0]: give exactly one of \"scale\" and \"radiance\"");
  expectError(err(R"({"version": 1, "emissive": [{"scale": 1}]})"), "emissive[0].material: expected a material index");
  expectError(err(R"({"version": 1, "emissive": [{"material": 0, "scale": [1, -2, 1]}]})"),
              "emissive[0].scale[1]: -2 is negative");
}

TEST(ClientLightSetJson, MissingFileIsNotFound) {
  auto u = LightUpdate::fromLightSetFile("/nonexistent/lights.json", nullptr);
  ASSERT_FALSE(u);
  EXPECT_EQ(u.status().code(), Code::kNotFound);
  EXPECT_NE(u.status().message().find("/nonexistent/lights.json"), std::string::npos);
}

}  // namespace
}  // namespace lightlink::client
