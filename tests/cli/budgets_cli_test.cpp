// The CLI's budgets (docs/cli.md "Limits" and "Exit codes"): absurd but in-range parameters
// fail at once with exit code 5 and a message naming the limit, never an abort.
#include <sys/wait.h>

#include <array>
#include <cstdio>
#include <string>

#include <gtest/gtest.h>

#include "clients/lightlink/exit_codes.h"
#include "tests/common/testing.h"

namespace lightlink {
namespace {

using CliRun = testing::ShellResult;

// Runs under `timeout` so that a regression that computes without bound fails (exit 124)
// instead of hanging the suite.
CliRun run(const std::string& args) {
  return testing::runShell("timeout 120 " + std::string(LIGHTLINK_CLI_PATH) + " " + args);
}

std::string demo() { return (testing::sourceDir() / "clients/demo/cornell_box.gltf").string(); }

TEST(CliBudgets, HugeResolutionFailsWithTheResourceExitCode) {
  testing::TempDir dir;
  // 16384 is inside --resolution's range; before the texel budget it ended in bad_alloc and
  // an abort (exit 134) with no message.
  const CliRun r = run("precompute -q " + demo() + " -o " + (dir / "a.llk").string() + " --resolution 16384");
  EXPECT_EQ(r.exit_code, cli::kExitResources) << r.output;
  EXPECT_NE(r.output.find("16384x16384"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("max_texels"), std::string::npos) << r.output;
}

TEST(CliBudgets, TinyTexelSizeFailsAtOnce) {
  testing::TempDir dir;
  const CliRun p = run("precompute -q " + demo() + " -o " + (dir / "a.llk").string() + " --texel-size 1e-9");
  EXPECT_EQ(p.exit_code, cli::kExitResources) << p.output;
  EXPECT_NE(p.output.find("max_texels"), std::string::npos) << p.output;
  const CliRun u = run("unwrap " + demo() + " -o " + (dir / "u.gltf").string() + " --texel-size 1e-9");
  EXPECT_EQ(u.exit_code, cli::kExitResources) << u.output;
  EXPECT_NE(u.output.find("max_texels"), std::string::npos) << u.output;
}

}  // namespace
}  // namespace lightlink
