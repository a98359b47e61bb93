// Surface rules (a bake config's cast_shadows / contribute_gi / receive_gi by name): what they
// select and set, in what order, and how bad files are refused.
#include "core/scene/surface_rules.h"

#include <gtest/gtest.h>

namespace lightlink::scene {
namespace {

Scene threeMeshes() {
  Scene s;
  Material glass, stone;
  glass.name = "window_glass";
  stone.name = "stone";
  s.materials = {glass, stone};
  for (const auto& [name, material] : {std::pair{"Window_01/0", 0}, std::pair{"Window_02/0", 0}, std::pair{"Wall/0", 1}}) {
    MeshInstance m;
    m.name = name;
    m.material = material;
    s.meshes.push_back(m);
  }
  return s;
}

TEST(SurfaceRules, SelectByMeshOrMaterialAndLaterRulesWin) {
  auto rules = parseSurfaceRules(R"({"version": 1, "surfaces": [
      {"material": "*glass", "cast_shadows": false, "contribute_gi": false},
      {"mesh": "Window_02", "cast_shadows": true},
      {"mesh": "Wall/?", "receive_gi": "off"},
      {"mesh": "Door*", "receive_gi": "volume"}]})",
                                 "rules.json");
  ASSERT_TRUE(rules) << rules.status().toString();
  Scene s = threeMeshes();
  const std::vector<std::size_t> selected = applySurfaceRules(s, *rules);
  EXPECT_EQ(selected, (std::vector<std::size_t>{2, 1, 1, 0}));
  EXPECT_FALSE(s.meshes[0].cast_shadows);
  EXPECT_TRUE(s.meshes[1].cast_shadows);  // the later rule
  EXPECT_FALSE(s.meshes[1].contribute_gi);
  EXPECT_TRUE(s.meshes[2].cast_shadows);
  EXPECT_EQ(s.meshes[2].receive_gi, ReceiveGi::kOff);
  EXPECT_TRUE(s.meshes[2].probe_lit);
  ASSERT_EQ(s.warnings.size(), 1u);  // the rule that selects nothing is named
  EXPECT_NE(s.warnings[0].find("Door*"), std::string::npos) << s.warnings[0];
}

TEST(SurfaceRules, GlobPatterns) {
  EXPECT_TRUE(globMatch("*", ""));
  EXPECT_TRUE(globMatch("a*c", "abbbc"));
  EXPECT_TRUE(globMatch("a?c", "abc"));
  EXPECT_FALSE(globMatch("a?c", "ac"));
  EXPECT_TRUE(globMatch("*glass*", "window_glass_02"));
  EXPECT_FALSE(globMatch("glass", "glass2"));
  EXPECT_TRUE(globMatch("a*b*c", "a_b_b_c"));
}

TEST(SurfaceRules, BadFilesAreRefusedNamingWhatIsWrong) {
  const std::pair<const char*, const char*> cases[] = {
      {"not json", "not valid JSON"},
      {R"({"surfaces": []})", "\"version\""},
      {R"({"version": 2, "surfaces": []})", "version 2 is not supported"},
      {R"({"version": 1, "surfaces": [], "extra": 1})", "unknown key 'extra'"},
      {R"({"version": 1, "surfaces": {}})", "must be an array"},
      {R"({"version": 1, "surfaces": [{"cast_shadows": false}]})", "surfaces[0] selects nothing"},
      {R"({"version": 1, "surfaces": [{"mesh": "a"}]})", "surfaces[0] sets no flag"},
      {R"({"version": 1, "surfaces": [{"mesh": "a", "cast_shadows": 0}]})", "surfaces[0].cast_shadows must be true or false"},
      {R"({"version": 1, "surfaces": [{"mesh": "a", "receive_gi": "none"}]})", "surfaces[0].receive_gi must be"},
      {R"({"version": 1, "surfaces": [{"mesh": "a", "castShadows": false}]})", "unknown key 'castShadows'"},
      {R"({"version": 1, "surfaces": [{"mesh": "", "cast_shadows": false}]})", "surfaces[0].mesh must be a non-empty"},
  };
  for (const auto& [text, expected] : cases) {
    auto r = parseSurfaceRules(text, "rules.json");
    ASSERT_FALSE(r) << text;
    EXPECT_EQ(r.status().code(), Code::kInvalidInput) << text;
    EXPECT_NE(r.status().message().find("rules.json"), std::string::npos) << r.status().message();
    EXPECT_NE(r.status().message().find(expected), std::string::npos) << r.status().message();
  }
}

TEST(SurfaceRules, CanonicalTextIsStableAndNormalised) {
  auto a = parseSurfaceRules(R"({"surfaces": [{"cast_shadows": false, "mesh": "x"}], "version": 1})", "a");
  auto b = parseSurfaceRules(R"({"version": 1, "surfaces": [{"mesh": "x", "cast_shadows": false}]})", "b");
  ASSERT_TRUE(a && b);
  EXPECT_EQ(a->canonical(), b->canonical());
  EXPECT_EQ(a->canonical(), R"({"version":1,"surfaces":[{"mesh":"x","cast_shadows":false}]})");
}

}  // namespace
}  // namespace lightlink::scene
