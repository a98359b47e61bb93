// Farm-scale CLI (docs/farm.md, docs/cli.md): `bake A B ... -o OUT` bakes every scene into
// its own folder past a failing one, writes summary.json and JUnit summary.xml and exits with
// the failed scene's code; a shared cache means an unchanged scene is not recomputed; and
// `precompute --shard I/N` + `merge` give the unsharded artifact, naming a missing shard.
#include <filesystem>
#include <fstream>
#include <iterator>
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

std::string slurp(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), {}};
}

nlohmann::json readJson(const fs::path& p) { return nlohmann::json::parse(slurp(p), nullptr, false); }

const std::string kDemo = (testing::sourceDir() / "clients/demo/cornell_box.gltf").string();
const std::string kFlags = " --preset draft --texel-size 0.03 --bands 2 --max-atlas 512 --hierarchy fast -q";

TEST(BatchBakeCli, OneBrokenSceneAmongGoodOnesGivesTheSummaryAndItsExitCode) {
  testing::TempDir dir;
  const std::string broken = testing::writeFile(dir / "broken.gltf", "{\"asset\": ");
  // The same scene under another folder: a folder name of its own, and the cached artifact.
  fs::create_directories(dir / "copy");
  fs::copy_file(kDemo, dir / "copy" / "cornell_box.gltf");
  const std::string copy = (dir / "copy" / "cornell_box.gltf").string();
  const fs::path out = dir / "out";
  const auto r = runCli("bake " + kDemo + " " + broken + " " + copy + " -o " + out.string() + kFlags);
  EXPECT_EQ(r.exit_code, cli::kExitBadInput) << r.output;
  EXPECT_NE(r.output.find("1 failed"), std::string::npos) << r.output;

  const auto s = readJson(out / "summary.json");
  ASSERT_FALSE(s.is_discarded()) << slurp(out / "summary.json");
  EXPECT_EQ(s["format"], "lightlink.bake-summary");
  EXPECT_EQ(s["scenes_total"], 3);
  EXPECT_EQ(s["scenes_ok"], 2);
  EXPECT_EQ(s["scenes_failed"], 1);
  const auto& scenes = s["scenes"];
  ASSERT_EQ(scenes.size(), 3u);
  EXPECT_EQ(scenes[0]["folder"], "cornell_box");
  EXPECT_EQ(scenes[0]["status"], "ok");
  EXPECT_EQ(scenes[1]["folder"], "broken");
  EXPECT_EQ(scenes[1]["status"], "error");
  EXPECT_EQ(scenes[1]["exit_code"], cli::kExitBadInput);
  EXPECT_NE(scenes[1]["message"].get<std::string>().find("broken.gltf"), std::string::npos) << scenes[1];
  EXPECT_EQ(scenes[2]["folder"], "cornell_box_gltf");
  EXPECT_EQ(scenes[2]["status"], "ok");
  // The baked scenes' outputs in their folders; the copy reused the first one's artifact.
  for (const char* folder : {"cornell_box", "cornell_box_gltf"}) {
    EXPECT_TRUE(fs::exists(out / folder / "report.json")) << folder;
    EXPECT_TRUE(fs::exists(out / folder / "irradiance.exr")) << folder;
  }
  EXPECT_EQ(scenes[0]["artifact"].get<std::string>().rfind("computed", 0), 0u) << scenes[0];
  EXPECT_EQ(scenes[2]["artifact"].get<std::string>().rfind("reused", 0), 0u) << scenes[2];

  const std::string xml = slurp(out / "summary.xml");
  EXPECT_NE(xml.find("<testsuite name=\"lightlink bake\" tests=\"3\" failures=\"0\" errors=\"1\""), std::string::npos)
      << xml;
  EXPECT_NE(xml.find("<testcase classname=\"lightlink.bake\" name=\"broken\""), std::string::npos) << xml;
  EXPECT_NE(xml.find("<error type=\"exit 2\""), std::string::npos) << xml;

  // Again without the broken scene: nothing recomputed, exit 0.
  const auto again = runCli("bake " + kDemo + " " + copy + " -o " + out.string() + kFlags);
  EXPECT_EQ(again.exit_code, 0) << again.output;
  const auto s2 = readJson(out / "summary.json");
  EXPECT_EQ(s2["scenes_failed"], 0);
  for (const auto& sc : s2["scenes"])
    EXPECT_EQ(sc["artifact"].get<std::string>().rfind("reused", 0), 0u) << sc;
}

TEST(BatchBakeCli, FailOnTripsAreFailuresWithTheirOutputsWritten) {
  testing::TempDir dir;
  // No light at all (the demo without its lights and emission): the outputs are written, and
  // --fail-on dark makes that a failure.
  nlohmann::json j = readJson(kDemo);
  j.erase("extensions");
  j["extensionsUsed"] = {"KHR_materials_emissive_strength"};
  for (auto& node : j["nodes"]) node.erase("extensions");
  for (auto& m : j["materials"]) m.erase("emissiveFactor");
  const std::string dark = testing::writeFile(dir / "dark.gltf", j.dump());
  const fs::path out = dir / "out";
  const auto r = runCli("bake " + dark + " --batch -o " + out.string() + kFlags + " --fail-on dark");
  const auto s = readJson(out / "summary.json");
  ASSERT_FALSE(s.is_discarded()) << r.output;
  ASSERT_EQ(s["scenes"].size(), 1u);
  EXPECT_EQ(r.exit_code, cli::kExitDark) << r.output;
  EXPECT_EQ(s["scenes"][0]["status"], "failed");
  EXPECT_TRUE(fs::exists(out / "dark" / "report.json"));
  EXPECT_NE(slurp(out / "summary.xml").find("<failure type=\"exit 7\""), std::string::npos);
}

TEST(ShardCli, PrecomputeShardsMergeIntoThePrecomputeAndAMissingShardIsNamed) {
  testing::TempDir dir;
  const std::string flags = " --preset draft --texel-size 0.03 --bands 2 --max-atlas 512 --hierarchy fast -q";
  ASSERT_EQ(runCli("precompute " + kDemo + " -o " + (dir / "whole.llk").string() + flags).exit_code, 0);
  for (int i = 0; i < 2; ++i) {
    // Appended piece by piece: GCC 12 warns (-Wrestrict, a false positive) on the one-line chain.
    std::string command = "precompute " + kDemo;
    command += " --shard ";
    command += std::to_string(i);
    command += "/2 -o ";
    std::string part = "p";
    part += std::to_string(i);
    command += (dir / part).string();
    command += flags;
    const auto r = runCli(command);
    ASSERT_EQ(r.exit_code, 0) << r.output;
  }
  const auto m = runCli("merge " + (dir / "p0").string() + " " + (dir / "p1").string() + " -o " +
                        (dir / "merged.llk").string() + " -q");
  ASSERT_EQ(m.exit_code, 0) << m.output;
  EXPECT_EQ(slurp(dir / "merged.llk"), slurp(dir / "whole.llk"));
  const auto missing = runCli("merge " + (dir / "p0").string() + " -o " + (dir / "m2.llk").string());
  EXPECT_EQ(missing.exit_code, cli::kExitBadInput) << missing.output;
  EXPECT_NE(missing.output.find("shard 1/2"), std::string::npos) << missing.output;
  EXPECT_FALSE(fs::exists(dir / "m2.llk"));
  const auto bad = runCli("precompute " + kDemo + " --shard 2/2 -o " + (dir / "p2").string() + flags);
  EXPECT_EQ(bad.exit_code, cli::kExitBadInput) << bad.output;
  EXPECT_NE(bad.output.find("--shard"), std::string::npos) << bad.output;
}

}  // namespace
}  // namespace lightlink
