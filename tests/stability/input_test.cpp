// NaN/Inf anywhere in the input is rejected with a message naming the field (DESIGN.md sec 6).
// One table over every number a glTF or a light set carries into the bake. JSON has no NaN
// or Inf literal: such values reach us as numbers that overflow (1e999 -> +Inf in double)
// or, subtler, numbers finite in double but infinite once stored as float (1e39 > FLT_MAX),
// and as raw NaN/Inf floats in binary accessors. tests/scene and tests/relight check single
// fields in depth; this table checks that no field is missed.
#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "core/relight/light_set.h"
#include "core/scene/load.h"
#include "tests/common/testing.h"
#include "tests/scene/gltf_builder.h"

namespace lightlink::stability {
namespace {

using testing::GltfBuilder;

// A valid file with a material, a point light, a spot light and a node transform, every
// number a distinct marker that a case replaces in the text.
GltfBuilder fullFile() {
  GltfBuilder b;
  const std::vector<glm::vec3> pos = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
  const std::vector<glm::vec3> nrm = {{0, 0, 1}, {0, 0, 1}, {0, 0, 1}};
  const int mesh = b.addTriangles(pos, {0, 1, 2}, "Floor", nrm);
  b.json()["materials"] = {
      {{"name", "Glow"},
       {"pbrMetallicRoughness",
        {{"baseColorFactor", {0.51, 0.52, 0.53, 0.54}}, {"metallicFactor", 0.055}, {"roughnessFactor", 0.56}}},
       {"emissiveFactor", {0.61, 0.66, 0.63}},
       {"extensions", {{"KHR_materials_emissive_strength", {{"emissiveStrength", 6.4}}}}}}};
  b.json()["meshes"][std::size_t(mesh)]["primitives"][0]["material"] = 0;
  b.json()["extensionsUsed"] = {"KHR_lights_punctual", "KHR_materials_emissive_strength"};
  b.json()["extensions"] = {
      {"KHR_lights_punctual",
       {{"lights",
         {{{"type", "point"}, {"name", "Bulb"}, {"intensity", 77.5}, {"color", {0.71, 0.72, 0.73}}, {"range", 7.4}},
          {{"type", "spot"},
           {"name", "Cone"},
           {"intensity", 88.5},
           {"spot", {{"innerConeAngle", 0.125}, {"outerConeAngle", 0.625}}}}}}}}};
  b.addNode({{"mesh", mesh},
             {"name", "Root"},
             {"translation", {0.25, 123.25, 0.375}},
             {"scale", {1.0625, 1.125, 1.1875}}});
  b.addNode({{"name", "Lamp"}, {"extensions", {{"KHR_lights_punctual", {{"light", 0}}}}}});
  b.addNode({{"name", "Spot"}, {"rotation", {0.0, 0.0, 0.0, 1.0}}, {"extensions", {{"KHR_lights_punctual", {{"light", 1}}}}}});
  return b;
}

struct TextCase {
  std::string marker;       // number in fullFile()'s text to replace
  std::string value;        // replacement
  std::string field;        // must appear in the message
};

TEST(StabilityInput, NonFiniteGltfNumbersAreRejectedNamingTheField) {
  testing::TempDir dir;
  const std::string base = fullFile().gltfText();
  {
    auto ok = scene::loadGltf(testing::writeFile(dir / "ok.gltf", base));
    ASSERT_TRUE(ok) << "the unmodified file must load: " << ok.status().toString();
  }
  const std::vector<TextCase> cases = {
      {"0.52", "1e999", "baseColorFactor"},
      {"0.055", "1e999", "metallicFactor"},
      {"0.56", "-1e999", "roughnessFactor"},
      {"0.66", "1e999", "emissiveFactor"},
      {"6.4", "1e999", "emissiveStrength"},
      {"77.5", "1e999", "intensity"},
      {"0.72", "1e999", "color"},
      {"7.4", "1e999", "range"},
      {"0.625", "1e999", "outerConeAngle"},
      {"0.125", "-1e999", "innerConeAngle"},
      {"123.25", "1e999", "translation"},
      {"1.125", "-1e999", "scale"},
      // Finite as a JSON double, infinite as the float the scene stores.
      {"77.5", "1e39", "intensity"},
      {"0.72", "1e39", "color"},
      {"7.4", "1e39", "range"},
      {"0.66", "1e39", "emissiveFactor"},
      {"6.4", "1e39", "emissiveStrength"},
      {"123.25", "1e39", "transform"},
  };
  int n = 0;
  for (const auto& c : cases) {
    std::string text = base;
    const std::size_t at = text.find(c.marker);
    ASSERT_NE(at, std::string::npos) << c.marker;
    ASSERT_EQ(text.find(c.marker, at + 1), std::string::npos) << "marker " << c.marker << " is not unique";
    text.replace(at, c.marker.size(), c.value);
    const std::string path = testing::writeFile(dir / ("case" + std::to_string(n++) + ".gltf"), text);
    auto s = scene::loadGltf(path);
    if (s) {
      ADD_FAILURE() << c.field << " = " << c.value << " was accepted";
      // What got through: the test prints it so the failure is actionable.
      for (const auto& l : s->lights) std::printf("  light intensity %g range %g\n", l.intensity, l.range);
      continue;
    }
    EXPECT_EQ(s.status().code(), Code::kInvalidInput) << s.status().toString();
    EXPECT_NE(s.status().message().find(c.field), std::string::npos)
        << c.field << " = " << c.value << ": the message does not name the field: " << s.status().message();
  }
}

TEST(StabilityInput, NonFiniteAccessorFloatsAreRejectedNamingTheAttribute) {
  testing::TempDir dir;
  const float nan = std::numeric_limits<float>::quiet_NaN(), inf = std::numeric_limits<float>::infinity();
  struct Case {
    std::vector<glm::vec3> pos, nrm;
    std::string field;
  };
  const std::vector<Case> cases = {
      {{{0, 0, 0}, {1, 0, 0}, {0, nan, 0}}, {}, "POSITION"},
      {{{0, 0, 0}, {-inf, 0, 0}, {0, 1, 0}}, {}, "POSITION"},
      {{{0, 0, 0}, {1, 0, 0}, {0, 1, 0}}, {{0, 0, 1}, {0, 0, nan}, {0, 0, 1}}, "NORMAL"},
      {{{0, 0, 0}, {1, 0, 0}, {0, 1, 0}}, {{inf, 0, 1}, {0, 0, 1}, {0, 0, 1}}, "NORMAL"},
  };
  int n = 0;
  for (const auto& c : cases) {
    GltfBuilder b;
    b.addNode({{"mesh", b.addTriangles(c.pos, {0, 1, 2}, "Floor", c.nrm)}});
    auto s = scene::loadGltf(b.writeGltf(dir / ("acc" + std::to_string(n++) + ".gltf")));
    ASSERT_FALSE(s) << c.field << " with a non-finite float was accepted";
    EXPECT_NE(s.status().message().find(c.field), std::string::npos) << s.status().message();
    EXPECT_NE(s.status().message().find("not finite"), std::string::npos) << s.status().message();
  }
}

TEST(StabilityInput, NonFiniteLightSetValuesAreRejectedNamingTheField) {
  // Through files (LightSet::load), as the CLI and the daemon read them: 1e999 fails inside
  // the JSON parser, 1e39 in the schema checks; both must name the field.
  const std::string base = R"({"version": 1,
    "lights": [{"id": "lamp", "type": "point", "position": [1.5, 2.5, 3.5], "intensity": 40.5,
                "color": [0.81, 0.82, 0.83], "range": 9.5},
               {"id": "spot", "type": "spot", "position": [0, 3, 0], "direction": [0.05, -1, 0.07],
                "intensity": 50.5, "inner_cone_angle": 0.3, "outer_cone_angle": 0.6}],
    "sky": {"radiance": [0.21, 0.22, 0.23]},
    "emissive": [{"material": 0, "scale": 2.75}, {"material": 1, "radiance": [4.1, 4.2, 4.3]}]})";
  const std::string sh_base = R"({"version": 1, "sky": {"sh": [[1,1,1],[0.1,0.2,0.3],[0,0,0],[0,0,0],
      [0,0,0],[0,0,0],[0,0,0],[0,0,0],[0,0,0.9]]}})";
  testing::TempDir dir;
  ASSERT_TRUE(relight::LightSet::load(testing::writeFile(dir / "ok.json", base)));
  ASSERT_TRUE(relight::LightSet::load(testing::writeFile(dir / "ok_sh.json", sh_base)));
  struct Case {
    const std::string* text;
    std::string marker, value, field;
  };
  const std::vector<Case> cases = {
      {&base, "40.5", "1e999", "lights[0].intensity"},   {&base, "0.82", "1e999", "lights[0].color[1]"},
      {&base, "3.5", "-1e999", "lights[0].position[2]"}, {&base, "9.5", "1e999", "lights[0].range"},
      {&base, "0.05", "1e999", "lights[1].direction[0]"}, {&base, "0.6", "1e999", "lights[1].outer_cone_angle"},
      {&base, "0.3,", "-1e999,", "lights[1].inner_cone_angle"},
      {&base, "0.21", "1e999", "sky.radiance[0]"},       {&base, "2.75", "1e999", "emissive[0].scale"},
      {&base, "4.3", "1e999", "emissive[1].radiance[2]"}, {&sh_base, "0.2", "1e999", "sky.sh[1][1]"},
      // Finite doubles that overflow float: past the parser, caught by the schema checks.
      {&base, "40.5", "1e39", "lights[0].intensity"},    {&base, "1.5", "1e39", "lights[0].position[0]"},
      {&base, "0.05", "-1e39", "lights[1].direction"},   {&sh_base, "0.2", "1e39", "sky.sh[1]"},
  };
  int n = 0;
  for (const auto& c : cases) {
    std::string text = *c.text;
    const std::size_t at = text.find(c.marker);
    ASSERT_NE(at, std::string::npos) << c.marker;
    ASSERT_EQ(text.find(c.marker, at + 1), std::string::npos) << "marker " << c.marker << " is not unique";
    text.replace(at, c.marker.size(), c.value);
    auto set = relight::LightSet::load(testing::writeFile(dir / ("set" + std::to_string(n++) + ".json"), text));
    if (set) {
      ADD_FAILURE() << c.field << " = " << c.value << " was accepted";
      continue;
    }
    EXPECT_EQ(set.status().code(), Code::kInvalidInput);
    EXPECT_NE(set.status().message().find(c.field), std::string::npos)
        << c.field << " = " << c.value << ": " << set.status().message();
  }
  // And through the API, where a NaN can arrive as such.
  relight::LightSet set;
  relight::LightEntry e;
  e.id = "nan";
  e.light.intensity = std::numeric_limits<float>::quiet_NaN();
  auto s = set.add(e);
  ASSERT_FALSE(s);
  EXPECT_NE(s.message().find("intensity"), std::string::npos) << s.message();
  e.light.intensity = 1.0f;
  e.light.position.y = std::numeric_limits<float>::infinity();
  s = set.add(e);
  ASSERT_FALSE(s);
  EXPECT_NE(s.message().find("position"), std::string::npos) << s.message();
  EXPECT_EQ(set.version(), 0u) << "a rejected edit must not change the set";
}

}  // namespace
}  // namespace lightlink::stability
