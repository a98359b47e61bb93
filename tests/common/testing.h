// Shared helpers for lightlink tests: where the shared scenes are, temporary folders
// that clean up after themselves, and writing small glTF fixtures from JSON text.
#pragma once

#include <filesystem>
#include <string>

namespace lightlink::testing {

// ../shared/scenes next to the repository, or "" when it is not there.
std::filesystem::path sharedScenesDir();

// The repository root (for committed fixtures such as the demo scene).
std::filesystem::path sourceDir();

// A fresh, empty directory under the system temp dir, removed by the destructor.
class TempDir {
 public:
  TempDir();
  ~TempDir();
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;
  const std::filesystem::path& path() const { return path_; }
  std::filesystem::path operator/(const std::string& name) const { return path_ / name; }

 private:
  std::filesystem::path path_;
};

// A command run through /bin/sh (tests/client/process.h runs argv with a time limit): its exit code (128 + signal when killed, as a shell
// reports it) and its stdout and stderr together.
struct ShellResult {
  int exit_code = -1;
  std::string output;
};
ShellResult runShell(const std::string& command);

// Writes `text` to `path` (binary, truncating) and returns the path as a string.
std::string writeFile(const std::filesystem::path& path, const std::string& text);

}  // namespace lightlink::testing
