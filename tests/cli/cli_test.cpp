// The `lightlink` CLI as a user runs it: real processes, exit codes, JSON on stdout.
#include <sys/stat.h>
#include <sys/wait.h>

#include <array>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "clients/lightlink/exit_codes.h"
#include "tests/common/escaping_scenes.h"
#include "tests/common/testing.h"

namespace lightlink {
namespace {

using ProcessResult = testing::ShellResult;
using testing::runShell;

std::string readAll(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

const std::string kCli = LIGHTLINK_CLI_PATH;

std::filesystem::path demoScene() { return testing::sourceDir() / "clients/demo/cornell_box.gltf"; }

TEST(DemoScene, CommittedFileMatchesGenerator) {
  testing::TempDir dir;
  const auto regenerated = dir / "cornell_box.gltf";
  const auto r = runShell(std::string(LIGHTLINK_MAKE_CORNELL_BOX_PATH) + " " + regenerated.string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_EQ(readAll(regenerated), readAll(demoScene()))
      << "clients/demo/cornell_box.gltf is stale: rerun make_cornell_box";
}

TEST(Inspect, DemoSceneJsonCounts) {
  const auto r = runShell(kCli + " inspect --json " + demoScene().string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const auto j = nlohmann::json::parse(r.output);
  EXPECT_EQ(j["triangles"], 112);  // 32 in the room and blocks + an 80-triangle probe
  EXPECT_EQ(j["static_triangles"], 32);
  EXPECT_EQ(j["dynamic_triangles"], 80);
  EXPECT_EQ(j["dynamic_mesh_instances"], 1);
  EXPECT_EQ(j["lights"]["point"], 1);
  EXPECT_EQ(j["lights"]["spot"], 0);
  EXPECT_EQ(j["emissive_materials"], 1);
  // The ceiling emitter is 130 mm x 105 mm.
  EXPECT_NEAR(j["emissive_area_m2"].get<double>(), 0.130 * 0.105, 1e-6);
  EXPECT_NEAR(j["bounds_m"]["max"][1].get<double>(), 0.5488, 1e-5);
  EXPECT_TRUE(j["lightmap_uv"]["unwrap_needed"].get<bool>());
}

TEST(Inspect, ShowsAlphaCutoutsAndInstancesThatCastNoShadows) {
  const auto scene = testing::sourceDir() / "tests/data/alpha/alpha_cards.gltf";
  const auto r = runShell(kCli + " inspect --json " + scene.string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const auto j = nlohmann::json::parse(r.output);
  EXPECT_EQ(j["alpha"]["mask_materials"], 1);
  EXPECT_EQ(j["alpha"]["blend_materials"], 1);
  EXPECT_EQ(j["alpha"]["cutout_mesh_instances"], 2);
  EXPECT_EQ(j["cast_shadows_false"]["mesh_instances"], 1);
  EXPECT_EQ(j["cast_shadows_false"]["names"], nlohmann::json::array({"glass_sheet/0"}));
  const auto text = runShell(kCli + " inspect " + scene.string());
  EXPECT_NE(text.output.find("1 MASK, 1 BLEND"), std::string::npos) << text.output;
  EXPECT_NE(text.output.find("cast no shadows: glass_sheet/0"), std::string::npos) << text.output;
}

TEST(Inspect, TextSummaryNamesTheEssentials) {
  const auto r = runShell(kCli + " inspect " + demoScene().string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("112 (32 static, 80 dynamic)"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("1 point, 0 spot, 0 directional"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("unwrap needed"), std::string::npos) << r.output;
}

TEST(Inspect, MissingFileIsBadInput) {
  const auto r = runShell(kCli + " inspect /nonexistent/scene.gltf");
  EXPECT_EQ(r.exit_code, cli::kExitBadInput) << r.output;
  EXPECT_NE(r.output.find("/nonexistent/scene.gltf"), std::string::npos) << r.output;
}

TEST(Inspect, MalformedGltfIsBadInputNamingTheFile) {
  testing::TempDir dir;
  const auto path = testing::writeFile(dir / "broken.gltf", "{ \"asset\": {\"version\": \"2.0\"}, \"meshes\": [ ");
  const auto r = runShell(kCli + " inspect " + path);
  EXPECT_EQ(r.exit_code, cli::kExitBadInput) << r.output;
  EXPECT_NE(r.output.find("broken.gltf"), std::string::npos) << r.output;
}

TEST(Precompute, WritesAnArtifactAndAReport) {
  testing::TempDir dir;
  const auto artifact = dir / "demo.llk";
  const auto report = dir / "report.json";
  const auto r = runShell(kCli + " precompute " + demoScene().string() + " -o " + artifact.string() +
                            " --surfels 512 --links 16 --rays 64 --resolution 32 -q --report " + report.string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_TRUE(std::filesystem::exists(artifact));
  const auto j = nlohmann::json::parse(readAll(report));
  EXPECT_EQ(j["counts"]["surfels"], 512);
  EXPECT_EQ(j["counts"]["lightmap_resolution"], 32);
  EXPECT_GT(j["links"]["lightmap"]["rays_per_second"].get<double>(), 0.0);
  EXPECT_EQ(j["triangles"], 112);
}

TEST(Precompute, BadParametersAreBadInputNamingTheOption) {
  for (const std::string bad : {"--bands 9", "--hierarchy bogus", "--surfels 0", "--grid maybe",
                                "--texel-size -1", "--subdivide 9"}) {
    const auto r = runShell(kCli + " precompute " + demoScene().string() + " -o /tmp/never.llk -q " + bad);
    EXPECT_EQ(r.exit_code, cli::kExitBadInput) << bad << ": " << r.output;
    EXPECT_NE(r.output.find(bad.substr(0, bad.find(' '))), std::string::npos) << bad << ": " << r.output;
  }
}

TEST(Unwrap, WritesGltfWithLightmapUvs) {
  testing::TempDir dir;
  const auto out = dir / "box_lm.gltf";
  const auto r = runShell(kCli + " unwrap " + demoScene().string() + " -o " + out.string() + " --json");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const auto report = nlohmann::json::parse(r.output);
  EXPECT_EQ(report["overlaps"], 0);
  const auto inspect = runShell(kCli + " inspect --json " + out.string());
  ASSERT_EQ(inspect.exit_code, 0) << inspect.output;
  const auto j = nlohmann::json::parse(inspect.output);
  EXPECT_FALSE(j["lightmap_uv"]["unwrap_needed"].get<bool>());
}

TEST(Bake, WritesEverythingThenReusesTheArtifact) {
  testing::TempDir dir;
  const std::string cmd = kCli + " bake " + demoScene().string() + " -o " + (dir / "out").string() +
                          " --preset draft --bounces 2 -q";
  const auto first = runShell(cmd);
  ASSERT_EQ(first.exit_code, 0) << first.output;
  for (const char* f : {"irradiance.exr", "lightmap_L00.exr", "lightmap_L22.exr", "direct.exr", "valid.exr",
                        "lightmap.png", "report.json", "grid_L00.exr", "grid_L22.exr", "grid_valid.exr", "grid.json",
                        "grid.raw", "grid_threejs.json", "grid_threejs.bin", "cornell_box_lm.gltf"})
    EXPECT_TRUE(std::filesystem::exists(dir / "out" / f)) << f;
  // The glTF points at its lighting: the grid's placement as grid.json states it.
  const auto gltf = nlohmann::json::parse(readAll(dir / "out" / "cornell_box_lm.gltf"));
  const auto grid_json = nlohmann::json::parse(readAll(dir / "out" / "grid.json"));
  ASSERT_TRUE(gltf["extensions"].contains("LIGHTLINK_lighting")) << gltf["extensionsUsed"];
  const auto& lighting = gltf["extensions"]["LIGHTLINK_lighting"];
  EXPECT_EQ(lighting["lightmap"]["sh"][0], "lightmap_L00.exr");
  EXPECT_EQ(lighting["irradiance"]["uri"], "irradiance.exr");
  EXPECT_EQ(gltf["images"].back()["uri"], "irradiance.exr") << "MOZ_lightmap binds the L0 map bake wrote";
  EXPECT_EQ(lighting["grid"]["dims"], grid_json["dims"]);
  EXPECT_EQ(lighting["grid"]["origin_m"], grid_json["origin_m"]);
  EXPECT_EQ(lighting["grid"]["spacing_m"], grid_json["spacing_m"]);
  EXPECT_EQ(lighting["grid"]["threejs"]["uri"], "grid_threejs.json");
  auto report = nlohmann::json::parse(readAll(dir / "out" / "report.json"));
  EXPECT_EQ(report["artifact"].get<std::string>().rfind("computed", 0), 0u) << report["artifact"];
  EXPECT_TRUE(report["effects_plan"].is_object());
  EXPECT_EQ(report["relight"]["backend"], "cpu");
  EXPECT_EQ(report["encoding"]["name"], "l2");

  const auto second = runShell(cmd);
  ASSERT_EQ(second.exit_code, 0) << second.output;
  report = nlohmann::json::parse(readAll(dir / "out" / "report.json"));
  EXPECT_EQ(report["artifact"].get<std::string>().rfind("reused", 0), 0u) << report["artifact"];

  // A damaged cached artifact is never used: the bake recomputes and replaces it.
  for (const auto& e : std::filesystem::directory_iterator(dir / "out" / "cache")) {
    std::string bytes = readAll(e.path());
    bytes[bytes.size() / 2] ^= 0x5a;
    testing::writeFile(e.path(), bytes);
  }
  const auto third = runShell(cmd);
  ASSERT_EQ(third.exit_code, 0) << third.output;
  report = nlohmann::json::parse(readAll(dir / "out" / "report.json"));
  EXPECT_NE(report["artifact"].get<std::string>().find("unusable"), std::string::npos) << report["artifact"];
  const auto fourth = runShell(cmd);
  report = nlohmann::json::parse(readAll(dir / "out" / "report.json"));
  EXPECT_EQ(report["artifact"].get<std::string>().rfind("reused", 0), 0u) << report["artifact"];
}

// Surface rules from a bake config (--surfaces): inspect shows what they set, bake lists the
// meshes without lightmap indirect light in report.json, and the rules are part of the
// artifact's cache key (a bake with other rules recomputes). A bad file is bad input naming it.
TEST(Bake, SurfaceRulesFileSetsFlagsAndReachesTheReportAndTheCacheKey) {
  testing::TempDir dir;
  const auto rules = dir / "surfaces.json";
  testing::writeFile(rules, R"({"version": 1, "surfaces": [
      {"mesh": "Blocks", "receive_gi": "off"},
      {"material": "Red", "cast_shadows": false, "contribute_gi": false}]})");
  const auto shown = runShell(kCli + " inspect --json --surfaces " + rules.string() + " " + demoScene().string());
  ASSERT_EQ(shown.exit_code, 0) << shown.output;
  const auto j = nlohmann::json::parse(shown.output);
  EXPECT_EQ(j["cast_shadows_false"]["names"], nlohmann::json::array({"RedWall/0"}));
  EXPECT_EQ(j["contribute_gi_false"]["names"], nlohmann::json::array({"RedWall/0"}));
  EXPECT_EQ(j["receive_gi"]["off"], 1);

  const std::string base = kCli + " bake " + demoScene().string() + " -o " + (dir / "out").string() +
                           " --preset draft --bounces 2 -q";
  ASSERT_EQ(runShell(base).exit_code, 0);
  const auto with_rules = runShell(base + " --surfaces " + rules.string());
  ASSERT_EQ(with_rules.exit_code, 0) << with_rules.output;
  const auto report = nlohmann::json::parse(readAll(dir / "out" / "report.json"));
  EXPECT_EQ(report["artifact"].get<std::string>().rfind("computed", 0), 0u) << report["artifact"];
  EXPECT_EQ(report["receive_gi"]["off"], nlohmann::json::array({"Blocks/0"}));

  testing::writeFile(dir / "bad.json", R"({"version": 1, "surfaces": [{"mesh": "Blocks", "receive_gi": "never"}]})");
  const auto bad = runShell(base + " --surfaces " + (dir / "bad.json").string());
  EXPECT_EQ(bad.exit_code, cli::kExitBadInput) << bad.output;
  EXPECT_NE(bad.output.find("surfaces[0].receive_gi"), std::string::npos) << bad.output;
  const auto missing = runShell(base + " --surfaces " + (dir / "missing.json").string());
  EXPECT_NE(missing.exit_code, 0);
  EXPECT_NE(missing.output.find("missing.json"), std::string::npos) << missing.output;
}

// The cache bake writes is private (0700 / 0600 whatever the umask), and a FIFO planted
// under the artifact's name is refused without blocking: the bake recomputes and replaces
// it. `timeout` bounds the run: before the fix the bake hung on opening the FIFO.
TEST(Bake, CacheIsPrivateAndAFifoInItDoesNotHang) {
  testing::TempDir dir;
  const auto cache = dir / "out" / "cache";
  const std::string cmd = "umask 0 && timeout 120 " + kCli + " bake " + demoScene().string() + " -o " +
                          (dir / "out").string() + " --preset draft --bounces 1 -q";
  const auto first = runShell(cmd);
  ASSERT_EQ(first.exit_code, 0) << first.output;
  std::vector<std::filesystem::path> artifacts;
  for (const auto& e : std::filesystem::directory_iterator(cache)) artifacts.push_back(e.path());
  ASSERT_EQ(artifacts.size(), 1u);
  const auto mode = [](const std::filesystem::path& p) {
    struct stat st {};
    return ::lstat(p.c_str(), &st) == 0 ? (st.st_mode & 07777) : 0xffffu;
  };
  EXPECT_EQ(mode(cache), 0700u);
  EXPECT_EQ(mode(artifacts[0]), 0600u);
  std::filesystem::remove(artifacts[0]);
  ASSERT_EQ(::mkfifo(artifacts[0].c_str(), 0600), 0);
  const auto second = runShell(cmd);
  ASSERT_EQ(second.exit_code, 0) << "exit 124 is the timeout: the bake hung on the FIFO\n" << second.output;
  const auto report = nlohmann::json::parse(readAll(dir / "out" / "report.json"));
  EXPECT_NE(report["artifact"].get<std::string>().find("FIFO"), std::string::npos) << report["artifact"];
  EXPECT_TRUE(std::filesystem::is_regular_file(artifacts[0])) << "the FIFO was replaced by the recomputed artifact";
}

TEST(Render, DrawsTheBakedCornellBox) {
  testing::TempDir dir;
  const auto out = dir / "out";
  auto r = runShell(kCli + " bake " + demoScene().string() + " -o " + out.string() + " --preset draft --bounces 1 -q");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const auto png = dir / "frame.png";
  r = runShell(kCli + " render " + (out / "cornell_box_lm.gltf").string() + " --bake " + out.string() + " -o " +
                 png.string() + " --width 96 --height 96");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_GT(std::filesystem::file_size(png), 1000u);
  // The room is lit from the lightmap, the dynamic probe from the grid, nothing unlit.
  EXPECT_NE(r.output.find(" 0 unlit"), std::string::npos) << r.output;
  EXPECT_EQ(r.output.find(" 0 from the grid"), std::string::npos) << r.output;
  EXPECT_EQ(r.output.find(" 0 pixels from the lightmap"), std::string::npos) << r.output;
  // The source scene has no lightmap UVs: a clear error, not a black picture.
  r = runShell(kCli + " render " + demoScene().string() + " --bake " + out.string() + " -o " + png.string());
  EXPECT_EQ(r.exit_code, cli::kExitBadInput) << r.output;
  EXPECT_NE(r.output.find("TEXCOORD_1"), std::string::npos) << r.output;

  // A crafted grid.raw (issue 44; render segfaulted on it): dims whose product wraps around
  // 2^64 to 11716 points, with a payload of exactly 11716 points. Rejected, naming the field.
  std::string grid = readAll(out / "grid.raw");
  ASSERT_GE(grid.size(), 48u);
  std::uint32_t bands = 0;
  std::memcpy(&bands, grid.data() + 16, 4);
  const std::uint32_t dims[3] = {3197508789u, 3355758485u, 659735396u};
  std::memcpy(grid.data() + 20, dims, 12);
  const std::size_t points = 11716;
  grid.resize(48);
  grid += std::string(points * 3 * bands * bands * sizeof(float), '\0') + std::string(points, '\1');
  testing::writeFile(out / "grid.raw", grid);
  r = runShell(kCli + " render " + (out / "cornell_box_lm.gltf").string() + " --bake " + out.string() + " -o " +
                 png.string() + " --width 96 --height 96");
  EXPECT_EQ(r.exit_code, cli::kExitBadInput) << r.output;
  EXPECT_NE(r.output.find("grid.raw: field 'dims'"), std::string::npos) << r.output;
}

// An OBJ in: bake writes the lightmapped scene as glTF (room_lm.gltf), which render reads.
TEST(Bake, AnObjSceneBakesToAGltfThatRenders) {
  testing::TempDir dir;
  // A closed 2 m room (faces wound to look inward) with an emissive panel under the ceiling.
  testing::writeFile(dir / "room.mtl", "newmtl wall\nKd 0.7 0.7 0.7\nnewmtl lamp\nKd 0 0 0\nKe 10 10 10\n");
  testing::writeFile(dir / "room.obj", R"(mtllib room.mtl
v -1 0 -1
v 1 0 -1
v 1 0 1
v -1 0 1
v -1 2 -1
v 1 2 -1
v 1 2 1
v -1 2 1
v -0.3 1.95 -0.3
v 0.3 1.95 -0.3
v 0.3 1.95 0.3
v -0.3 1.95 0.3
o Room
usemtl wall
f 1 2 3 4
f 5 8 7 6
f 1 5 6 2
f 2 6 7 3
f 3 7 8 4
f 4 8 5 1
o Lamp
usemtl lamp
f 9 10 11 12
)");
  const auto out = dir / "out";
  auto r = runShell(kCli + " bake " + (dir / "room.obj").string() + " -o " + out.string() +
                      " --preset draft --bounces 1 -q");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  ASSERT_TRUE(std::filesystem::exists(out / "room_lm.gltf")) << r.output;
  const auto png = dir / "frame.png";
  r = runShell(kCli + " render " + (out / "room_lm.gltf").string() + " --bake " + out.string() + " -o " +
                 png.string() + " --eye 0,1,0.9 --target 0,1,-1 --width 64 --height 64");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_EQ(r.output.find(" 0 pixels from the lightmap"), std::string::npos) << r.output;
}

TEST(Compare, MeasuresTheBakeAgainstTheReference) {
  testing::TempDir dir;
  const auto out = dir / "cmp";
  const auto r = runShell(kCli + " compare " + demoScene().string() + " --preset draft --max-points 40 " +
                            "--target-error 0.05 -q -o " + out.string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const auto j = nlohmann::json::parse(readAll(out / "compare.json"));
  EXPECT_EQ(j["points"], 40);
  for (const char* part : {"total", "indirect"}) {
    const double rmse = j[part]["rel_rmse"].get<double>(), bias = j[part]["bias"].get<double>();
    // A draft bake of the Cornell box is within tens of percent of the truth, not orders
    // of magnitude off: this catches unit or convention mismatches between the two.
    EXPECT_GT(rmse, 0.0) << part;
    EXPECT_LT(rmse, 0.5) << part;
    EXPECT_NEAR(bias, 1.0, 0.3) << part;
  }
  EXPECT_TRUE(std::filesystem::exists(out / "error_total.png"));
  EXPECT_TRUE(std::filesystem::exists(out / "error_indirect.png"));
  // Issue 46: the near-contact band (the box's wall/floor/ceiling lines) and the interior are
  // reported apart, leaks counted, and a leak map written.
  EXPECT_EQ(j["error_floor"]["fraction_of_mean"].get<double>(), 0.05);
  const int band = j["near_contact"]["points"].get<int>(), inner = j["interior"]["points"].get<int>();
  EXPECT_GT(band, 0);
  EXPECT_GT(inner, 0);
  EXPECT_EQ(band + inner, 40);
  EXPECT_GT(j["near_contact"]["total"]["mean_reference"].get<double>(), 0.0);
  EXPECT_TRUE(j["leaks"].contains("leaks") && j["leaks"].contains("missing_light")) << j["leaks"].dump();
  EXPECT_TRUE(j["total"].contains("lit_rel_rmse"));
  EXPECT_TRUE(std::filesystem::exists(out / "leaks.png"));
  // The worst points, worst first, each placed in the world and in the lightmap.
  const auto& worst = j["worst_points"];
  ASSERT_EQ(worst.size(), 10u);
  for (std::size_t k = 0; k < worst.size(); ++k) {
    EXPECT_EQ(worst[k]["position"].size(), 3u);
    EXPECT_EQ(worst[k]["texel"].size(), 2u);
    if (k > 0) EXPECT_GE(worst[k - 1]["rel_error"].get<double>(), worst[k]["rel_error"].get<double>());
  }
  EXPECT_LE(worst[0]["rel_error"].get<double>(), j["total"]["max_rel_error"].get<double>() * 1.0001);
  EXPECT_GE(worst[0]["rel_error"].get<double>(), j["total"]["max_rel_error"].get<double>() * 0.9999);
  const auto bad = runShell(kCli + " compare " + demoScene().string() + " --against guesswork -q");
  EXPECT_EQ(bad.exit_code, cli::kExitBadInput) << bad.output;
  const auto bad_floor = runShell(kCli + " compare " + demoScene().string() + " --error-floor 0 -q");
  EXPECT_EQ(bad_floor.exit_code, cli::kExitBadInput) << bad_floor.output;
  EXPECT_NE(bad_floor.output.find("--error-floor"), std::string::npos) << bad_floor.output;
}

TEST(Bake, BadLightSetAndPresetAreBadInput) {
  testing::TempDir dir;
  const auto lights = testing::writeFile(
      dir / "lights.json", R"({"version": 1, "lights": [{"id": "sun", "type": "directional", "intensity": -5}]})");
  auto r = runShell(kCli + " bake " + demoScene().string() + " -o " + (dir / "out").string() + " -q --lights " + lights);
  EXPECT_EQ(r.exit_code, cli::kExitBadInput) << r.output;
  EXPECT_NE(r.output.find("lights[0].intensity"), std::string::npos) << r.output;
  r = runShell(kCli + " bake " + demoScene().string() + " -o " + (dir / "out").string() + " -q --preset ultra");
  EXPECT_EQ(r.exit_code, cli::kExitBadInput) << r.output;
  EXPECT_NE(r.output.find("--preset"), std::string::npos) << r.output;
}

TEST(Cli, UnknownSubcommandIsUsageError) {
  const auto r = runShell(kCli + " frobnicate");
  EXPECT_EQ(r.exit_code, cli::kExitUsage) << r.output;
}

// A daemon token in argv is visible to every user in ps: refused before any connection,
// naming the alternatives.
TEST(Cli, DaemonTokenInArgvIsRefused) {
  const auto r = runShell(kCli + " watch --target 127.0.0.1:1 --scene s1 --scene-token t1 --count 1 --timeout 2000"
                                   " --token 0123456789abcdef0123");
  EXPECT_EQ(r.exit_code, cli::kExitBadInput) << r.output;
  EXPECT_NE(r.output.find("--token-file"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("LIGHTLINK_TOKEN"), std::string::npos) << r.output;
}

// A scene may make the CLI read files only inside its own folder (docs/cli.md "Files a scene
// may read"): `..`, an absolute path (also from `/`, where tinygltf fell back to the working
// directory) and a symlink out are refused by every scene command, naming the entry and the
// flag; --allow-outside-scene reads them.
TEST(Cli, SceneCommandsReadOnlyInsideTheSceneFolder) {
  for (testing::Escape how : {testing::Escape::kDotDot, testing::Escape::kAbsolute, testing::Escape::kSymlink}) {
    SCOPED_TRACE(testing::escapeName(how));
    testing::TempDir dir;
    const std::string scene = testing::writeEscapingScene(dir.path(), how).string();
    const std::string out = (dir / "out").string();
    for (const std::string& command : {"inspect " + scene, "unwrap " + scene + " -o " + out + "/lm.gltf",
                                       "precompute " + scene + " -q -o " + out + "/a.llk",
                                       "bake " + scene + " -q --preset draft -o " + out}) {
      const auto r = runShell("cd / && " + kCli + " " + command);
      EXPECT_EQ(r.exit_code, cli::kExitBadInput) << command << "\n" << r.output;
      EXPECT_NE(r.output.find("buffers[0].uri"), std::string::npos) << command << "\n" << r.output;
      EXPECT_NE(r.output.find("--allow-outside-scene"), std::string::npos) << command << "\n" << r.output;
    }
    const auto allowed = runShell("cd / && " + kCli + " inspect --allow-outside-scene " + scene);
    EXPECT_EQ(allowed.exit_code, cli::kExitOk) << allowed.output;
    const auto unwrapped =
        runShell(kCli + " unwrap --allow-outside-scene " + scene + " -o " + out + "/lm.gltf");
    EXPECT_EQ(unwrapped.exit_code, cli::kExitOk) << unwrapped.output;
  }
}

// The attack of issue 44: an index buffer that is someone else's file. Refused by default;
// allowed, the out-of-range index is named by position, never by the bytes it holds.
TEST(Cli, MessagesNeverQuoteFileContent) {
  testing::TempDir dir;
  const std::string scene = testing::writeSecretReadingScene(dir.path()).string();
  for (const std::string& flags : {std::string(), std::string("--allow-outside-scene ")}) {
    const auto r = runShell(kCli + " inspect " + flags + scene);
    EXPECT_EQ(r.exit_code, cli::kExitBadInput) << r.output;
    EXPECT_EQ(r.output.find(testing::secretFirstIndex()), std::string::npos) << "quotes the file: " << r.output;
    EXPECT_EQ(r.output.find("TOPS"), std::string::npos) << r.output;
    if (flags.empty()) {
      EXPECT_NE(r.output.find("buffers[1].uri"), std::string::npos) << r.output;
    }
  }
}

}  // namespace
}  // namespace lightlink
