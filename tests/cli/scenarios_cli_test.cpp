// `lightlink bake --scenario NAME=FILE` (docs/outputs.md "Lighting scenarios"): one relight per
// scenario over the one precompute, each scenario's lighting in scenarios/NAME/, a manifest,
// and clear errors for bad specs before anything is written.
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "clients/lightlink/exit_codes.h"
#include "tests/common/testing.h"

namespace lightlink {
namespace {

namespace fs = std::filesystem;

testing::ShellResult runCli(const std::string& args) {
  return testing::runShell("timeout 120 " + std::string(LIGHTLINK_CLI_PATH) + " " + args);
}

nlohmann::json readJson(const fs::path& p) {
  std::ifstream in(p);
  return nlohmann::json::parse(in, nullptr, false);
}

void writeText(const fs::path& p, const std::string& text) { std::ofstream(p) << text; }

std::string slurp(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), {}};
}

const std::string kDemo = (testing::sourceDir() / "clients/demo/cornell_box.gltf").string();
const std::string kFlags = " --preset draft --texel-size 0.03 --bands 2 --max-atlas 512 --grid on --hierarchy fast -q";

TEST(ScenariosCli, EachScenarioIsRelitIntoItsOwnFolderFromOnePrecompute) {
  testing::TempDir dir;
  // Day: a bright light near the left wall. Night: the room's own light off, a dim one right.
  writeText(dir / "day.json", R"({"version": 1, "lights": [
      {"id": "sun", "type": "point", "position": [-0.2, 0.4, 0.0], "intensity": 3}]})");
  writeText(dir / "night.json", R"({"version": 1, "emissive_baked": true, "lights": [
      {"id": "lamp", "type": "point", "position": [0.2, 0.2, 0.1], "intensity": 0.3}]})");
  const fs::path out = dir / "bake";
  const auto r = runCli("bake " + kDemo + " -o " + out.string() + kFlags + " --scenario day=" +
                        (dir / "day.json").string() + " --scenario night=" + (dir / "night.json").string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const auto manifest = readJson(out / "scenarios.json");
  ASSERT_FALSE(manifest.is_discarded());
  EXPECT_EQ(manifest["format"], "lightlink.scenarios");
  EXPECT_EQ(manifest["version"], 1);
  ASSERT_EQ(manifest["scenarios"].size(), 2u);
  EXPECT_EQ(manifest["scenarios"][0]["name"], "day");
  EXPECT_EQ(manifest["scenarios"][1]["folder"], "scenarios/night");
  for (const std::string name : {"day", "night"})
    for (const auto& f : manifest["scenarios"][name == "day" ? 0 : 1]["outputs"])
      EXPECT_TRUE(fs::exists(out / "scenarios" / name / f.get<std::string>())) << name << "/" << f;
  EXPECT_TRUE(fs::exists(out / "scenarios" / "day" / "grid.json"));
  // Different lights give different lighting; the base (no scenario) is written too.
  EXPECT_NE(slurp(out / "scenarios" / "day" / "lightmap_L00.exr"), slurp(out / "scenarios" / "night" / "lightmap_L00.exr"));
  EXPECT_TRUE(fs::exists(out / "irradiance.exr"));
  const auto report = readJson(out / "report.json");
  ASSERT_EQ(report["scenarios"].size(), 2u);
  EXPECT_GT(report["scenarios"][0]["relight_ms"].get<double>(), 0.0);
  EXPECT_EQ(report["scenarios"][1]["lighting"]["no_light"], false);
  // One precompute: the artifact cache holds one artifact.
  int artifacts = 0;
  for (const auto& e : fs::directory_iterator(out / "cache")) artifacts += e.path().extension() == ".llk";
  EXPECT_EQ(artifacts, 1);
}

TEST(ScenariosCli, BadScenarioSpecsAreRefusedNamingWhatIsWrong) {
  testing::TempDir dir;
  writeText(dir / "ok.json", R"({"version": 1, "lights": []})");
  writeText(dir / "bad.json", R"({"version": 1, "lights": [{"id": "x", "type": "point", "intensity": -1}]})");
  const std::string ok = (dir / "ok.json").string();
  const struct {
    std::string spec, message;
  } cases[] = {
      {"--scenario day", "expected NAME=LIGHTS.json"},
      {"--scenario ../up=" + ok, "must not start with '.'"},
      {"--scenario a/b=" + ok, "only letters"},
      {"--scenario day=" + (dir / "missing.json").string(), "missing.json"},
      {"--scenario day=" + (dir / "bad.json").string(), "intensity"},
      {"--scenario day=" + ok + " --scenario day=" + ok, "named twice"},
  };
  for (const auto& c : cases) {
    const fs::path out = dir / "o";
    const auto r = runCli("bake " + kDemo + " -o " + out.string() + kFlags + " " + c.spec);
    EXPECT_EQ(r.exit_code, cli::kExitBadInput) << c.spec << "\n" << r.output;
    EXPECT_NE(r.output.find(c.message), std::string::npos) << c.spec << "\n" << r.output;
    EXPECT_FALSE(fs::exists(out / "irradiance.exr")) << c.spec << ": nothing is written for a bad spec";
  }
}

}  // namespace
}  // namespace lightlink
