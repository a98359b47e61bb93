// One light-set contract: core (lights::LightSet, what the CLI and the daemon read) and the
// client library (LightUpdate) accept and reject the same documents, with the same message.
// Documents: the committed light sets (fuzz corpus and regressions, level and benchmark light
// sets) and one inline document per rule of docs/lightset.md.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "clients/client/light_update.h"
#include "core/lights/light_set.h"
#include "proto/lightlink.pb.h"
#include "tests/common/testing.h"

namespace lightlink::client {
namespace {

namespace fs = std::filesystem;

struct Document {
  std::string name;
  std::string text;
};

// Every *.json under the folders of the source tree that hold light sets.
std::vector<Document> committedLightSets() {
  std::vector<Document> docs;
  for (const char* dir : {"tests/fuzz/corpus/lightset", "tests/fuzz/regressions/lightset", "tests/levels/lights",
                          "bench/accuracy/lights"}) {
    const fs::path root = fs::path(LIGHTLINK_SOURCE_DIR) / dir;
    if (!fs::is_directory(root)) continue;
    for (const auto& entry : fs::directory_iterator(root)) {
      if (entry.path().extension() != ".json") continue;
      std::ifstream in(entry.path(), std::ios::binary);
      std::stringstream ss;
      ss << in.rdbuf();
      docs.push_back({fs::relative(entry.path(), LIGHTLINK_SOURCE_DIR).string(), ss.str()});
    }
  }
  return docs;
}

// One document per rule: accepted ones first, then one mistake each.
std::vector<Document> ruleDocuments() {
  const std::vector<std::string> texts = {
      R"({"version": 1})",
      R"({"version": 1, "lights": [{"id": "p", "type": "point", "position": [0, 0, 0], "direction": [0, 0, 1]}]})",
      R"({"version": 1, "lights": [{"id": "s", "type": "spot", "inner_cone_angle": 0.1, "outer_cone_angle": 1.5}]})",
      R"({"version": 1, "lights": [{"id": "d", "type": "directional", "direction": [0, -3, 0], "baked": false}]})",
      R"({"version": 1, "lights": [{"id": "p", "type": "point", "inner_cone_angle": 1.0}]})",
      R"({"version": 1, "sky": {"sh": [[1,1,1],[0,-1,0],[0,0,0],[0,0,0],[0,0,0],[0,0,0],[0,0,0],[0,0,0],[0,0,0]]}})",
      R"({"version": 1, "emissive": [{"material": 3, "scale": 2}, {"material": 3, "radiance": [1, 2, 3]}]})",
      R"({"version": 1, "emissive_baked": false})",
      R"([])",
      R"({"lights": []})",
      R"({"version": 2})",
      R"({"version": "1"})",
      R"({"version": 1, "colour": 1})",
      R"({"version": 1, "lights": {}})",
      R"({"version": 1, "lights": [3]})",
      R"({"version": 1, "lights": [{"type": "point"}]})",
      R"({"version": 1, "lights": [{"id": "", "type": "point"}]})",
      R"({"version": 1, "lights": [{"id": "a", "type": "point"}, {"id": "a", "type": "point"}]})",
      R"({"version": 1, "lights": [{"id": "a"}]})",
      R"({"version": 1, "lights": [{"id": "a", "type": "area"}]})",
      R"({"version": 1, "lights": [{"id": "a", "type": 1}]})",
      R"({"version": 1, "lights": [{"id": "a", "type": "point", "colour": [1, 1, 1]}]})",
      R"({"version": 1, "lights": [{"id": "a", "type": "point", "intensity": -1}]})",
      R"({"version": 1, "lights": [{"id": "a", "type": "point", "intensity": 1e13}]})",
      R"({"version": 1, "lights": [{"id": "a", "type": "point", "intensity": 1e300}]})",
      R"({"version": 1, "lights": [{"id": "a", "type": "point", "intensity": "x"}]})",
      R"({"version": 1, "lights": [{"id": "a", "type": "point", "color": [1, -1, 1]}]})",
      R"({"version": 1, "lights": [{"id": "a", "type": "point", "color": [1, 1]}]})",
      R"({"version": 1, "lights": [{"id": "a", "type": "point", "range": -2}]})",
      R"({"version": 1, "lights": [{"id": "a", "type": "point", "direction": [0, 0, 0]}]})",
      R"({"version": 1, "lights": [{"id": "a", "type": "directional", "direction": [0, 0, 0]}]})",
      R"({"version": 1, "lights": [{"id": "a", "type": "spot", "outer_cone_angle": 2}]})",
      R"({"version": 1, "lights": [{"id": "a", "type": "spot", "outer_cone_angle": 0}]})",
      R"({"version": 1, "lights": [{"id": "a", "type": "spot", "inner_cone_angle": 0.9}]})",
      R"({"version": 1, "lights": [{"id": "a", "type": "point", "inner_cone_angle": 0.5, "outer_cone_angle": 0.4}]})",
      R"({"version": 1, "lights": [{"id": "a", "type": "point", "baked": "yes"}]})",
      R"({"version": 1, "lights": [{"id": "a", "type": "point", "name": 3}]})",
      R"({"version": 1, "lights": [{"id": "ghost", "remove": true}]})",
      R"({"version": 1, "lights": [{"id": "ghost", "remove": "yes"}]})",
      R"({"version": 1, "sky": []})",
      R"({"version": 1, "sky": {"radiance": [0, -1, 0]}})",
      R"({"version": 1, "sky": {"sh": [[0, 0, 0]]}})",
      R"({"version": 1, "sky": {"colour": [0, 0, 0]}})",
      R"({"version": 1, "emissive": {}})",
      R"({"version": 1, "emissive": [{"scale": 1}]})",
      R"({"version": 1, "emissive": [{"material": -3, "scale": 1}]})",
      R"({"version": 1, "emissive": [{"material": 0, "scale": 1, "radiance": 2}]})",
      R"({"version": 1, "emissive": [{"material": 0}]})",
      R"({"version": 1, "emissive": [{"material": 0, "scale": [1, -2, 1]}]})",
      R"({"version": 1, "emissive_baked": 1})",
  };
  std::vector<Document> docs;
  for (std::size_t i = 0; i < texts.size(); ++i) docs.push_back({fmt::format("rule document {}", i), texts[i]});
  return docs;
}

// A light set that had the scene's ids, for the documents that modify or remove them.
lights::LightSet sceneSet() {
  lights::LightSet set;
  lights::LightEntry light0{"light0", {}, true};
  lights::LightEntry sun{"sun", {}, true};
  sun.light.kind = lights::Light::Kind::kDirectional;
  EXPECT_TRUE(set.add(light0));
  EXPECT_TRUE(set.add(sun));
  return set;
}

// The verdicts of both readers on one document; `known` is the client's view of the ids.
void expectSameVerdict(const Document& doc, const lights::LightSet& core_before, const std::set<std::string>& known) {
  lights::LightSet core = core_before;
  Status core_status;
  auto patch = lights::LightSetPatch::parse(doc.text);
  if (!patch) core_status = patch.status();
  else core_status = core.apply(*patch);
  auto client = LightUpdate::fromLightSetText(doc.text, &known);
  const Status client_status = client ? Status{} : client.status();
  EXPECT_EQ(bool(core_status), bool(client_status))
      << doc.name << ": core says '" << core_status.toString() << "', the client '" << client_status.toString()
      << "'\n" << doc.text;
  EXPECT_EQ(core_status.message(), client_status.message()) << doc.name << "\n" << doc.text;
  if (core_status && client) {
    // What the client sends describes the same lights: every id the core set gained is an add.
    std::set<std::string> added;
    for (const auto& l : client->proto().add()) added.insert(l.id());
    for (const auto& e : core.lights()) {
      if (!core_before.find(e.id)) {
        EXPECT_TRUE(added.contains(e.id)) << doc.name << ": " << e.id;
      }
    }
  }
}

TEST(LightSetContract, CoreAndClientAgreeOnEveryCommittedLightSet) {
  const std::vector<Document> docs = committedLightSets();
  ASSERT_GE(docs.size(), 5u) << "light sets not found under " << LIGHTLINK_SOURCE_DIR;
  const lights::LightSet scene = sceneSet();
  for (const Document& doc : docs) {
    expectSameVerdict(doc, lights::LightSet{}, {});
    expectSameVerdict(doc, scene, {"light0", "sun"});
  }
}

TEST(LightSetContract, CoreAndClientAgreeOnEveryRule) {
  for (const Document& doc : ruleDocuments()) expectSameVerdict(doc, lights::LightSet{}, {});
  // Not JSON at all: both name the place the parser stopped.
  expectSameVerdict({"truncated", R"({"version": 1, "lights": [{"id": "a", "intensity": 1e999}]})"}, {}, {});
  expectSameVerdict({"empty", ""}, {}, {});
}

// With the scene's ids, the client sees only the fields of a modify, not the light they land
// on: it may accept what the merged light fails (the daemon then answers), never the reverse.
TEST(LightSetContract, ClientIsNeverStricterThanCoreOnModifies) {
  const lights::LightSet scene = sceneSet();
  const std::set<std::string> known = {"light0", "sun"};
  for (const std::string& text :
       {std::string(R"({"version": 1, "lights": [{"id": "sun", "intensity": 5, "direction": [0, -1, 0]}]})"),
        std::string(R"({"version": 1, "lights": [{"id": "light0", "type": "spot", "outer_cone_angle": 0}]})"),
        std::string(R"({"version": 1, "lights": [{"id": "light0", "intensity": -5}]})"),
        std::string(R"({"version": 1, "lights": [{"id": "sun", "remove": true}, {"id": "x", "type": "point"}]})")}) {
    lights::LightSet core = scene;
    auto patch = lights::LightSetPatch::parse(text);
    const bool core_ok = patch && core.apply(*patch);
    const bool client_ok = bool(LightUpdate::fromLightSetText(text, &known));
    if (core_ok) {
      EXPECT_TRUE(client_ok) << text;
    }
  }
}

}  // namespace
}  // namespace lightlink::client
