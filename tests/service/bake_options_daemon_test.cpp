// One set of bake options everywhere (issue 45): what `lightlink bake` takes as flags, OpenScene
// takes in `options`, and the same options reach the artifact (the same cache key).
#include <sys/wait.h>

#include <array>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "tests/common/testing.h"
#include "tests/service/daemon_harness.h"

namespace lightlink::testing {
namespace {

namespace fs = std::filesystem;

using CliRun = testing::ShellResult;

CliRun runCli(const std::string& args) {
  return testing::runShell("timeout 120 " + std::string(LIGHTLINK_CLI_PATH) + " " + args);
}

fs::path demo() { return sourceDir() / "clients/demo/cornell_box.gltf"; }

v1::OpenSceneRequest demoRequest(const std::map<std::string, std::string>& options) {
  v1::OpenSceneRequest r;
  r.set_path(demo().string());
  r.set_backend(v1::BACKEND_CPU);
  for (const auto& [k, v] : options) (*r.mutable_options())[k] = v;
  return r;
}

TEST(BakeOptionsEverywhere, SameOptionsGiveTheSameArtifactFromBakeAndFromOpenScene) {
  TempDir tmp;
  const CliRun bake = runCli("bake " + demo().string() + " -o " + (tmp / "out").string() +
                             " --preset draft --texel-size 0.02 --bands 2 -q");
  ASSERT_EQ(bake.exit_code, 0) << bake.output;
  std::ifstream in(tmp / "out" / "report.json");
  const auto report = nlohmann::json::parse(in);
  const std::string bake_key = report["cache_key"].get<std::string>();

  DaemonProcess d(tmp / "cache", {"--backend", "cpu"});
  ASSERT_TRUE(d.ok()) << d.error();
  auto rpc = d.rpc();
  v1::SceneOpened opened;
  // The map in another order than the command line, and the preset last: it still applies first.
  ASSERT_TRUE(openScene(*rpc, demoRequest({{"bands", "2"}, {"texel-size", "0.02"}, {"preset", "draft"}}), &opened).ok())
      << d.log();
  EXPECT_EQ(opened.cache_key(), bake_key);
  EXPECT_EQ(opened.bands(), 2);
  // A map entry wins over the deprecated typed field of the same option.
  v1::OpenSceneRequest legacy = demoRequest({{"bands", "2"}, {"texel-size", "0.02"}});
  legacy.set_preset("draft");
  legacy.set_bands(3);
  v1::SceneOpened again;
  ASSERT_TRUE(openScene(*rpc, legacy, &again).ok()) << d.log();
  EXPECT_EQ(again.cache_key(), bake_key);
  EXPECT_TRUE(again.artifact_reused());
  // `lightlink open` sends its flags as the options map.
  const CliRun open = runCli("open --target " + d.target() + " --preset draft --texel-size 0.02 --bands 2 " +
                             demo().string());
  ASSERT_EQ(open.exit_code, 0) << open.output;
  EXPECT_NE(open.output.find(bake_key), std::string::npos) << open.output;
}

TEST(BakeOptionsEverywhere, OpenSceneRejectsUnknownAndBadOptionsNamingThem) {
  TempDir tmp;
  DaemonProcess d(tmp / "cache", {"--backend", "cpu"});
  ASSERT_TRUE(d.ok()) << d.error();
  auto rpc = d.rpc();
  for (const auto& [key, value] : std::vector<std::pair<std::string, std::string>>{
           {"texel-sise", "0.1"}, {"bands", "9"}, {"grid", "maybe"}, {"max-atlas", "8"}, {"bounces", "257"}}) {
    const grpc::Status st = openScene(*rpc, demoRequest({{"preset", "draft"}, {key, value}}), nullptr);
    EXPECT_EQ(st.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << key;
    EXPECT_NE(st.error_message().find("options." + key), std::string::npos) << st.error_message();
  }
}

// The lightmap SH of a scene opened with `options`, at its initial version.
std::string lightmapSh(LightlinkRpc& rpc, const std::map<std::string, std::string>& options) {
  v1::SceneOpened opened;
  const grpc::Status st = openScene(rpc, demoRequest(options), &opened);
  EXPECT_TRUE(st.ok()) << st.error_message();
  v1::RelightRequest rq;
  rq.mutable_scene()->set_scene_id(opened.scene_id());
  rq.mutable_scene()->set_token(opened.scene_token());
  rq.set_version(opened.version());
  rq.mutable_spec()->set_precision(v1::PRECISION_FLOAT);
  auto ctx = context();
  auto reader = rpc.Relight(ctx.get(), rq);
  Result res;
  std::string err;
  EXPECT_TRUE(readOne(reader.get(), res, &err).ok()) << err;
  return res.payloads[v1::PAYLOAD_LIGHTMAP_SH];
}

// The relight options of the one table ("bounces", "link-form", "seams", "indirect") set the
// scene's relight; none is accepted and then dropped.
TEST(BakeOptionsEverywhere, RelightOptionsReachTheScene) {
  TempDir tmp;
  DaemonProcess d(tmp / "cache", {"--backend", "cpu"});
  ASSERT_TRUE(d.ok()) << d.error();
  auto rpc = d.rpc();
  const std::string raw = lightmapSh(*rpc, {{"preset", "draft"}, {"indirect", "raw"}});
  ASSERT_FALSE(raw.empty()) << d.log();
  // Compared as bools: a failure must not print megabytes of payload.
  EXPECT_TRUE(lightmapSh(*rpc, {{"preset", "draft"}}) == raw) << "raw is the default";
  EXPECT_FALSE(lightmapSh(*rpc, {{"preset", "draft"}, {"indirect", "smooth"}}) == raw) << "--indirect smooth was dropped";
  EXPECT_FALSE(lightmapSh(*rpc, {{"preset", "draft"}, {"bounces", "0"}}) == raw) << "--bounces was dropped";
}

std::string bakeOptionsHelp(const std::string& command) {
  const CliRun r = runCli(command + " --help");
  const auto begin = r.output.find("Bake options:");
  if (begin == std::string::npos) return "no \"Bake options\" in `" + command + " --help`:\n" + r.output;
  return r.output.substr(begin, r.output.find("\n\n", begin) - begin);
}

TEST(BakeOptionsEverywhere, BakeCompareOpenAndPrecomputeListTheSameOptions) {
  const std::string bake = bakeOptionsHelp("bake");
  EXPECT_NE(bake.find("--texel-size"), std::string::npos) << bake;
  EXPECT_NE(bake.find("--max-pages"), std::string::npos) << bake;
  EXPECT_EQ(bakeOptionsHelp("compare"), bake);
  EXPECT_EQ(bakeOptionsHelp("open"), bake);
  EXPECT_EQ(bakeOptionsHelp("precompute"), bake);
}

TEST(BakeOptionsEverywhere, OpenRefusesToUploadAnythingButGltf) {
  TempDir tmp;
  const std::string obj = writeFile(tmp / "room.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
  // No daemon at this target: the refusal comes before any connection.
  const CliRun r = runCli("open --upload --target 127.0.0.1:1 --timeout 2000 " + obj);
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("room.obj"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find(".glb"), std::string::npos) << r.output;
  // A bad option is refused before connecting too.
  const CliRun bad = runCli("open --target 127.0.0.1:1 --timeout 2000 --bands 7 " + demo().string());
  EXPECT_EQ(bad.exit_code, 2) << bad.output;
  EXPECT_NE(bad.output.find("--bands"), std::string::npos) << bad.output;
}

}  // namespace
}  // namespace lightlink::testing
