// Confinement of the daemon (issue 44): OpenScene by path only under --scene-root, one answer
// for every path outside whether or not it exists, uploads only when no root is configured,
// and a scene inside a root still reads nothing outside its own folder.
#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>

#include <gtest/gtest.h>

#include "tests/common/escaping_scenes.h"
#include "tests/common/testing.h"
#include "tests/service/daemon_harness.h"

namespace lightlink::testing {
namespace {

namespace fs = std::filesystem;

std::vector<std::string> rootFlags(const fs::path& root) {
  return {"--backend", "cpu", "--log-level", "debug", "--scene-root", root.string()};
}

v1::OpenSceneRequest requestFor(const fs::path& path) {
  v1::OpenSceneRequest r = cornellRequest();
  r.set_path(path.string());
  return r;
}

TEST(Confine, PathsOutsideTheRootsGetOneAnswerWhetherOrNotTheyExist) {
  TempDir tmp;
  const fs::path root = tmp / "root", outside = tmp / "outside";
  fs::create_directories(root);
  fs::create_directories(outside);
  const std::string secret = writeFile(outside / "secret.gltf", "not a scene, but it exists: 0123456789");
  fs::create_symlink(secret, root / "link-to-existing.gltf");
  fs::create_symlink(outside / "missing.gltf", root / "link-to-missing.gltf");
  fs::create_directory_symlink(outside, root / "dir-link");
  fs::create_directory_symlink(outside / "no-such-dir", root / "dangling-dir-link");
  DaemonProcess d(tmp / "cache", rootFlags(root));
  ASSERT_TRUE(d.ok()) << d.error();
  auto rpc = d.rpc();

  const std::vector<fs::path> probes = {
      secret,                                  // exists
      outside / "missing.gltf",                // does not
      outside,                                 // a directory
      "/etc/passwd",                           // a system file
      root / ".." / "outside" / "secret.gltf", // `..` out of a root
      root / "link-to-existing.gltf",          // symlinks inside the root leading out
      root / "link-to-missing.gltf",
      root / "dir-link" / "secret.gltf",
      root / "dir-link" / "missing.gltf",
      root / "dangling-dir-link" / "scene.gltf",
  };
  std::set<std::pair<int, std::string>> answers;
  for (const fs::path& p : probes) {
    const grpc::Status st = openScene(*rpc, requestFor(p), nullptr);
    EXPECT_EQ(st.error_code(), grpc::StatusCode::PERMISSION_DENIED) << p << ": " << st.error_message();
    EXPECT_EQ(st.error_message().find(p.filename().string()), std::string::npos)
        << "echoes the request: " << st.error_message();
    answers.insert({st.error_code(), st.error_message()});
  }
  EXPECT_EQ(answers.size(), 1u) << "paths outside the roots are told apart";
  // Inside a root, a missing scene is simply not found.
  EXPECT_EQ(openScene(*rpc, requestFor(root / "missing.gltf"), nullptr).error_code(), grpc::StatusCode::NOT_FOUND);
}

TEST(Confine, WithoutRootsOnlyUploadsOpen) {
  TempDir tmp;
  const std::string config = writeFile(tmp / "lightlinkd.json", R"({"scene_roots": [], "backend": "cpu"})");
  DaemonProcess d(tmp / "cache", {"--config", config});
  ASSERT_TRUE(d.ok()) << d.error();
  auto rpc = d.rpc();
  const grpc::Status by_path = openScene(*rpc, cornellRequest(), nullptr);
  EXPECT_EQ(by_path.error_code(), grpc::StatusCode::PERMISSION_DENIED) << by_path.error_message();
  EXPECT_NE(by_path.error_message().find("--scene-root"), std::string::npos) << by_path.error_message();
  std::ifstream in(sourceDir() / "clients/demo/cornell_box.gltf", std::ios::binary);
  std::stringstream bytes;
  bytes << in.rdbuf();
  v1::OpenSceneRequest upload = cornellRequest();
  upload.set_gltf_bytes(bytes.str());
  const grpc::Status uploaded = openScene(*rpc, upload, nullptr);
  EXPECT_TRUE(uploaded.ok()) << uploaded.error_message() << "\n" << d.log();
}

// The root holds the scene's folder and the folder it escapes to: the root check passes, the
// loader's folder rule does not.
TEST(Confine, SceneUnderARootReadsNothingOutsideItsFolder) {
  TempDir tmp;
  const fs::path root = tmp / "root";
  std::vector<fs::path> scenes;
  for (Escape how : {Escape::kDotDot, Escape::kAbsolute, Escape::kSymlink})
    scenes.push_back(writeEscapingScene(root / escapeName(how), how));
  const fs::path secret_scene = writeSecretReadingScene(root / "secret");
  DaemonProcess d(tmp / "cache", rootFlags(root));
  ASSERT_TRUE(d.ok()) << d.error();
  auto rpc = d.rpc();
  for (const fs::path& scene : scenes) {
    const grpc::Status st = openScene(*rpc, requestFor(scene), nullptr);
    EXPECT_EQ(st.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << scene << ": " << st.error_message();
    EXPECT_NE(st.error_message().find("buffers[0].uri"), std::string::npos) << st.error_message();
  }
  const grpc::Status st = openScene(*rpc, requestFor(secret_scene), nullptr);
  EXPECT_EQ(st.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << st.error_message();
  EXPECT_NE(st.error_message().find("buffers[1].uri"), std::string::npos) << st.error_message();
  EXPECT_EQ(st.error_message().find(secretFirstIndex()), std::string::npos) << st.error_message();
  EXPECT_EQ(st.error_message().find("TOPS"), std::string::npos) << st.error_message();
}

}  // namespace
}  // namespace lightlink::testing
