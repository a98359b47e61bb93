// One set of bake options (issue 45): `bake` and `compare` given the same flags bake with the
// same options (the canonical string the cache key covers), and refuse the same bad ones.
#include <sys/wait.h>

#include <array>
#include <cstdio>
#include <fstream>
#include <string>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "clients/lightlink/exit_codes.h"
#include "tests/common/testing.h"

namespace lightlink {
namespace {

using CliResult = testing::ShellResult;

CliResult runCli(const std::string& args) {
  return testing::runShell("timeout 120 " + std::string(LIGHTLINK_CLI_PATH) + " " + args);
}

nlohmann::json readJson(const std::filesystem::path& p) {
  std::ifstream in(p);
  return nlohmann::json::parse(in, nullptr, false);
}

const std::string kDemo = (testing::sourceDir() / "clients/demo/cornell_box.gltf").string();
const std::string kFlags = " --preset draft --texel-size 0.03 --bands 2 --max-atlas 512 --grid off --hierarchy fast -q";

TEST(BakeOptionsCli, BakeAndCompareBakeWithTheSameOptions) {
  testing::TempDir dir;
  const CliResult bake = runCli("bake " + kDemo + " -o " + (dir / "bake").string() + kFlags);
  ASSERT_EQ(bake.exit_code, 0) << bake.output;
  const CliResult cmp = runCli("compare " + kDemo + " --max-points 16 --target-error 0.1 -o " + (dir / "cmp").string() + kFlags);
  ASSERT_EQ(cmp.exit_code, 0) << cmp.output;
  const auto b = readJson(dir / "bake" / "report.json");
  const auto c = readJson(dir / "cmp" / "compare.json");
  const std::string options = b["precompute"]["options"].get<std::string>();
  EXPECT_NE(options.find("bands=2"), std::string::npos) << options;
  EXPECT_NE(options.find("max_atlas=512"), std::string::npos) << options;
  EXPECT_EQ(c["options"].get<std::string>(), options);
}

TEST(BakeOptionsCli, EveryBakingCommandRefusesTheSameBadOptionNamingIt) {
  testing::TempDir dir;
  for (const std::string bad : {"--bands 5", "--max-atlas 8", "--texel-size -1", "--grid maybe", "--uv reuse"}) {
    for (const std::string cmd : {"bake " + kDemo + " -o " + (dir / "o").string(), "compare " + kDemo,
                                  "precompute " + kDemo + " -o " + (dir / "a.llk").string()}) {
      const CliResult r = runCli(cmd + " -q " + bad);
      EXPECT_EQ(r.exit_code, cli::kExitBadInput) << cmd << " " << bad << ": " << r.output;
      EXPECT_NE(r.output.find(bad.substr(0, bad.find(' '))), std::string::npos) << cmd << " " << bad << ": " << r.output;
    }
  }
}

}  // namespace
}  // namespace lightlink
