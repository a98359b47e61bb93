// Confinement of scene I/O (core/scene/scene_files.h): a scene reads files only inside its
// own folder unless told otherwise, only regular files, and its messages never quote the
// bytes of a buffer.
#include <fcntl.h>
#include <sys/stat.h>
#include <sys/syscall.h>
#include <unistd.h>
#include <linux/openat2.h>

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <filesystem>
#include <mutex>
#include <thread>

#include <gtest/gtest.h>

#include "core/scene/load.h"
#include "tests/common/escaping_scenes.h"
#include "tests/common/testing.h"

namespace lightlink::scene {
namespace {

namespace fs = std::filesystem;
using testing::Escape;
using testing::TempDir;

LoadOptions allowOutside() {
  LoadOptions o;
  o.files.allow_outside_folder = true;
  return o;
}

// The working directory, restored at the end of the scope (tinygltf used to fall back to it).
class WorkingDirectory {
 public:
  explicit WorkingDirectory(const fs::path& dir) : old_(fs::current_path()) { fs::current_path(dir); }
  ~WorkingDirectory() { fs::current_path(old_); }

 private:
  fs::path old_;
};

TEST(SceneFiles, UriLeavingTheFolderIsRefusedNamingTheEntry) {
  for (Escape how : {Escape::kDotDot, Escape::kAbsolute, Escape::kSymlink}) {
    SCOPED_TRACE(testing::escapeName(how));
    TempDir dir;
    const std::string path = testing::writeEscapingScene(dir.path(), how).string();
    // From `/` an absolute URI was also found through tinygltf's working-directory fallback.
    WorkingDirectory cwd("/");
    Expected<Scene> scene = loadGltf(path);
    ASSERT_FALSE(scene) << "read a buffer outside the scene's folder";
    EXPECT_EQ(scene.status().code(), Code::kInvalidInput);
    const std::string& m = scene.status().message();
    EXPECT_NE(m.find(path), std::string::npos) << m;
    EXPECT_NE(m.find("buffers[0].uri"), std::string::npos) << m;
    EXPECT_NE(m.find(how == Escape::kAbsolute ? "absolute path" : "escapes the scene's folder"), std::string::npos)
        << m;
    if (how == Escape::kSymlink) {
      EXPECT_NE(m.find("symbolic link"), std::string::npos) << m;
    }
  }
}

// A link to something missing outside is outside too (weakly_canonical would stop at the
// dangling link and call the path inside): the answer must not depend on what exists there.
TEST(SceneFiles, DanglingLinkOutIsOutside) {
  TempDir dir;
  fs::create_directories(dir / "scene");
  fs::create_directory_symlink(dir / "elsewhere" / "missing", dir / "scene" / "assets");
  const std::string path = testing::writeFile(dir / "scene" / "s.gltf", testing::triangleGltf("assets/geo.bin"));
  Expected<Scene> scene = loadGltf(path);
  ASSERT_FALSE(scene);
  EXPECT_NE(scene.status().message().find("escapes the scene's folder"), std::string::npos)
      << scene.status().message();
  Expected<fs::path> resolved = resolvePath(dir / "scene" / "assets" / ".." / "x");
  ASSERT_TRUE(resolved);
  EXPECT_EQ(*resolved, *resolvePath(dir.path()) / "elsewhere" / "x");  // `..` taken after the link
}

TEST(SceneFiles, AllowOutsideFolderReadsThem) {
  for (Escape how : {Escape::kDotDot, Escape::kAbsolute, Escape::kSymlink}) {
    SCOPED_TRACE(testing::escapeName(how));
    TempDir dir;
    Expected<Scene> scene = loadGltf(testing::writeEscapingScene(dir.path(), how).string(), allowOutside());
    ASSERT_TRUE(scene) << scene.status().message();
    EXPECT_EQ(scene->meshes.size(), 1u);
  }
}

TEST(SceneFiles, SubfolderUrisInsideTheFolderLoad) {
  TempDir dir;
  fs::create_directories(dir / "scene" / "sub dir" / "deeper");
  testing::writeFile(dir / "scene" / "sub dir" / "deeper" / "geo.bin", testing::triangleBin());
  // Percent-encoded, with a `..` that stays inside, and a symlink that stays inside.
  fs::create_directory_symlink(dir / "scene" / "sub dir", dir / "scene" / "alias");
  for (const char* uri : {"sub%20dir/deeper/geo.bin", "sub%20dir/deeper/../deeper/geo.bin", "alias/deeper/geo.bin"}) {
    SCOPED_TRACE(uri);
    const std::string path = testing::writeFile(dir / "scene" / "inside.gltf", testing::triangleGltf(uri));
    Expected<Scene> scene = loadGltf(path);
    ASSERT_TRUE(scene) << scene.status().message();
    EXPECT_EQ(scene->meshes.size(), 1u);
  }
}

TEST(SceneFiles, BufferBytesAreNeverQuoted) {
  TempDir dir;
  const std::string path = testing::writeSecretReadingScene(dir.path()).string();
  Expected<Scene> refused = loadGltf(path);
  ASSERT_FALSE(refused);
  EXPECT_NE(refused.status().message().find("buffers[1].uri"), std::string::npos) << refused.status().message();
  // Even where reading it is allowed, the out-of-range index is named by position, not value.
  Expected<Scene> allowed = loadGltf(path, allowOutside());
  ASSERT_FALSE(allowed);
  const std::string& m = allowed.status().message();
  EXPECT_NE(m.find("element 0"), std::string::npos) << m;
  EXPECT_EQ(m.find(testing::secretFirstIndex()), std::string::npos) << "quotes the file's bytes: " << m;
  EXPECT_EQ(m.find("TOPS"), std::string::npos) << m;
}

// A FIFO named by a scene is refused, not opened for a read that waits for a writer. (Before
// the fix the load blocked; the helper thread then opens the writing end so the test ends.)
TEST(SceneFiles, FifoIsRefusedWithoutBlocking) {
  TempDir dir;
  fs::create_directories(dir / "scene");
  const fs::path fifo = dir / "scene" / "geo.bin";
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  const std::string path = testing::writeFile(dir / "scene" / "fifo.gltf", testing::triangleGltf("geo.bin"));
  std::mutex m;
  std::condition_variable cv;
  bool done = false;
  std::thread unblock([&] {
    std::unique_lock lock(m);
    while (!cv.wait_for(lock, std::chrono::seconds(5), [&] { return done; })) {
      const int fd = ::open(fifo.c_str(), O_WRONLY | O_NONBLOCK);  // a blocked reader then reads EOF
      if (fd >= 0) ::close(fd);
    }
  });
  Expected<Scene> scene = loadGltf(path);
  {
    std::lock_guard lock(m);
    done = true;
  }
  cv.notify_all();
  unblock.join();
  ASSERT_FALSE(scene);
  EXPECT_NE(scene.status().message().find("not a regular file"), std::string::npos) << scene.status().message();
}


// The window between the check and the open: a folder inside the scene's folder is checked,
// then swapped for a link that leads out. The read resolves the path again beneath the
// scene's folder and refuses it, instead of reading the outside file.
TEST(SceneFiles, LinkSwappedInAfterTheCheckIsRefused) {
  open_how probe{};
  probe.flags = O_PATH | O_CLOEXEC;
  const long fd = ::syscall(SYS_openat2, AT_FDCWD, ".", &probe, sizeof(probe));
  if (fd < 0) GTEST_SKIP() << "openat2 is not available here (errno " << errno << "): the check stands alone";
  ::close(static_cast<int>(fd));
  TempDir dir;
  const fs::path scene_dir = dir / "scene";
  fs::create_directories(scene_dir / "sub");
  fs::create_directories(dir / "outside");
  testing::writeFile(scene_dir / "sub" / "data.bin", "inside");
  testing::writeFile(dir / "outside" / "data.bin", "SECRET");
  const fs::path folder = fs::canonical(scene_dir);
  const fs::path checked = folder / "sub" / "data.bin";
  Expected<std::string> before = readRegularFileBeneath(folder, checked, "buffers[0].uri");
  ASSERT_TRUE(before) << before.status().message();
  EXPECT_EQ(*before, "inside");
  fs::remove_all(scene_dir / "sub");
  fs::create_directory_symlink(fs::canonical(dir / "outside"), scene_dir / "sub");
  Expected<std::string> after = readRegularFileBeneath(folder, checked, "buffers[0].uri");
  ASSERT_FALSE(after) << "read the outside file through the swapped link: " << *after;
  EXPECT_NE(after.status().message().find("escapes the scene's folder"), std::string::npos) << after.status().message();
  EXPECT_EQ(after.status().message().find("SECRET"), std::string::npos);
}

}  // namespace
}  // namespace lightlink::scene
