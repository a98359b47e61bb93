// `lightlink bake` tells its user what went wrong without failing the bake: ingest warnings
// (a missing or undecodable texture), a bake with no light, on stderr and in report.json,
// with the exit codes docs/cli.md promises under --fail-on; and report.json and --version
// name the version and commit (issue 45, deliverables 6 and 8).
#include <sys/wait.h>

#include <array>
#include <cstdio>
#include <fstream>
#include <sstream>
#include <string>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "clients/lightlink/bake_findings.h"
#include "clients/lightlink/exit_codes.h"
#include "tests/common/testing.h"

namespace lightlink {
namespace {

using ProcessRun = testing::ShellResult;

ProcessRun runProcess(const std::string& command) { return testing::runShell(command); }

nlohmann::json readJson(const std::filesystem::path& path) {
  std::ifstream in(path);
  std::stringstream ss;
  ss << in.rdbuf();
  return nlohmann::json::parse(ss.str());
}

std::string joined(const nlohmann::json& warnings) {
  std::string out;
  for (const auto& w : warnings) out += w.get<std::string>() + "\n";
  return out;
}

const std::string kCli = LIGHTLINK_CLI_PATH;

nlohmann::json demo() {
  std::ifstream in(testing::sourceDir() / "clients/demo/cornell_box.gltf");
  return nlohmann::json::parse(in);
}

std::string bake(const std::string& scene, const std::filesystem::path& out, const std::string& extra = "") {
  return kCli + " bake " + scene + " -o " + out.string() + " --preset draft --bounces 1 -q " + extra;
}

TEST(BakeWarnings, MissingAndUndecodableTexturesBakeWithTheWarningsListed) {
  testing::TempDir dir;
  nlohmann::json j = demo();
  // White's base colour is a file that is not there, Red's a .png of garbage bytes.
  j["images"] = {{{"uri", "missing.png"}}, {{"uri", "garbage.png"}}};
  j["textures"] = {{{"source", 0}}, {{"source", 1}}};
  j["materials"][0]["pbrMetallicRoughness"]["baseColorTexture"] = {{"index", 0}};
  j["materials"][1]["pbrMetallicRoughness"]["baseColorTexture"] = {{"index", 1}};
  testing::writeFile(dir / "garbage.png", "\x89PNG\r\n\x1a\n this is not an image");
  const std::string scene = testing::writeFile(dir / "box.gltf", j.dump());

  const ProcessRun r = runProcess(bake(scene, dir / "out"));
  ASSERT_EQ(r.exit_code, cli::kExitOk) << r.output;
  const nlohmann::json report = readJson(dir / "out" / "report.json");
  const std::string warnings = joined(report["warnings"]);
  EXPECT_NE(warnings.find("texture 0: image 0 'missing.png' was not decoded"), std::string::npos) << warnings;
  EXPECT_NE(warnings.find("image 1: cannot be decoded"), std::string::npos) << warnings;
  EXPECT_NE(warnings.find("texture 1: image 1 'garbage.png' was not decoded"), std::string::npos) << warnings;
  // Printed too (on stderr, -q or not), each naming the scene file.
  EXPECT_NE(r.output.find("lightlink bake: warning: " + scene + ": texture 0"), std::string::npos) << r.output;
  EXPECT_EQ(report["lighting"]["no_light"], false);
  EXPECT_EQ(report["load"]["images_decoded"], 0);
  // The version and the commit the binary was built from.
  EXPECT_FALSE(report["lightlink"]["version"].get<std::string>().empty());
  EXPECT_FALSE(report["lightlink"]["commit"].get<std::string>().empty());
  // --fail-on warning makes CI fail it, with every output still written.
  const ProcessRun strict = runProcess(bake(scene, dir / "out", "--fail-on warning"));
  EXPECT_EQ(strict.exit_code, cli::kExitWarnings) << strict.output;
  EXPECT_TRUE(std::filesystem::exists(dir / "out" / "lightmap_L00.exr"));
  EXPECT_EQ(runProcess(bake(scene, dir / "out", "--fail-on dark")).exit_code, cli::kExitOk);
}

TEST(BakeWarnings, ABakeWithNoLightSaysSoAndFailsOnlyWhenAsked) {
  testing::TempDir dir;
  nlohmann::json j = demo();
  j.erase("extensions");
  j["extensionsUsed"] = {"KHR_materials_emissive_strength"};
  for (auto& node : j["nodes"]) node.erase("extensions");
  for (auto& m : j["materials"]) m.erase("emissiveFactor");
  const std::string scene = testing::writeFile(dir / "dark.gltf", j.dump());

  const ProcessRun r = runProcess(bake(scene, dir / "out"));
  ASSERT_EQ(r.exit_code, cli::kExitOk) << r.output;
  const nlohmann::json report = readJson(dir / "out" / "report.json");
  EXPECT_EQ(report["lighting"]["no_light"], true);
  EXPECT_NE(joined(report["warnings"]).find("no light"), std::string::npos) << report["warnings"];
  EXPECT_NE(r.output.find("warning: " + scene + ": scene: no light"), std::string::npos) << r.output;
  EXPECT_EQ(runProcess(bake(scene, dir / "out", "--fail-on dark")).exit_code, cli::kExitDark);
  EXPECT_EQ(runProcess(bake(scene, dir / "out", "--fail-on warning")).exit_code, cli::kExitDark);
  const ProcessRun bad = runProcess(bake(scene, dir / "out", "--fail-on sometimes"));
  EXPECT_EQ(bad.exit_code, cli::kExitBadInput) << bad.output;
  EXPECT_NE(bad.output.find("--fail-on"), std::string::npos) << bad.output;
}

// The dark-bake rule on a relight result made by hand: a lit scene whose lightmap has no
// positive direct value and no positive DC term in any channel is "all black".
TEST(BakeWarnings, AnAllBlackLightmapIsNamedAndMapsToTheDarkExitCode) {
  scene::Scene scene;
  scene.source_path = "lit.gltf";
  relight::RelightResult r;
  r.bands = 2;  // 4 coefficients a channel: DC at 0, 4, 8 of a texel's 12
  r.lightmap_sh.assign(2 * 12, 0.0f);
  r.lightmap_sh[1] = 0.5f;  // a positive higher-order coefficient carries no light alone
  r.direct.assign(2, glm::vec3(0.0f));
  r.plan.punctual = true;
  cli::BakeFindings f = cli::collectFindings(scene, nlohmann::ordered_json::object(), r);
  EXPECT_FALSE(f.no_light);
  EXPECT_TRUE(f.all_black);
  ASSERT_EQ(f.warnings.size(), 1u);
  EXPECT_NE(f.warnings[0].find("lit.gltf: lightmap: every texel is black"), std::string::npos) << f.warnings[0];
  EXPECT_EQ(cli::bakeExitCode(f, cli::FailOn::kNever), cli::kExitOk);
  EXPECT_EQ(cli::bakeExitCode(f, cli::FailOn::kDark), cli::kExitDark);
  EXPECT_EQ(cli::bakeExitCode(f, cli::FailOn::kWarning), cli::kExitDark);

  r.lightmap_sh[12 + 4] = 1e-3f;  // texel 1, green DC
  EXPECT_FALSE(cli::lightmapAllBlack(r));
  r.lightmap_sh[12 + 4] = 0.0f;
  r.direct[0].z = 1e-3f;
  EXPECT_FALSE(cli::lightmapAllBlack(r));
  f = cli::collectFindings(scene, nlohmann::ordered_json{{"notes", {"a note"}}, {"warnings", {"w: x"}}}, r);
  EXPECT_FALSE(f.dark());
  EXPECT_EQ(f.notes, std::vector<std::string>{"a note"});
  EXPECT_EQ(f.warnings, std::vector<std::string>{"w: x"});
  EXPECT_EQ(cli::bakeExitCode(f, cli::FailOn::kDark), cli::kExitOk);
  EXPECT_EQ(cli::bakeExitCode(f, cli::FailOn::kWarning), cli::kExitWarnings);
}

TEST(BakeWarnings, VersionNamesTheCommit) {
  const ProcessRun r = runProcess(kCli + " --version");
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("lightlink 0."), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("(commit "), std::string::npos) << r.output;
}

}  // namespace
}  // namespace lightlink
