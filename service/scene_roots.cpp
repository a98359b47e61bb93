#include "service/scene_roots.h"

namespace lightlink::service {
namespace fs = std::filesystem;

Expected<SceneRoots> SceneRoots::resolve(const std::vector<std::string>& dirs) {
  SceneRoots out;
  for (const std::string& dir : dirs) {
    std::error_code ec;
    if (dir.empty()) return invalidInput("--scene-root: must not be empty");
    fs::path canonical = fs::canonical(dir, ec);
    if (ec || !fs::is_directory(canonical, ec))
      return invalidInput("--scene-root {}: not an existing directory", dir);
    out.roots_.push_back(std::move(canonical));
  }
  return out;
}

Expected<std::string> SceneRoots::admit(const std::string& requested) const {
  if (roots_.empty()) {
    return invalidInput("path: this daemon opens no scene by path (it has no --scene-root); send the scene's "
                        "bytes (gltf_bytes, `lightlink open --upload`)");
  }
  // One answer for every refusal below: a path that does not resolve, one outside the roots
  // and one whose link leads out all read alike, existing or not.
  const Status outside = invalidInput("path: not under one of the daemon's --scene-root folders");
  if (requested.find('\0') != std::string::npos) return outside;  // the OS would read a shorter path
  std::error_code ec;
  const fs::path absolute = fs::absolute(requested, ec);
  if (ec) return outside;
  const fs::path canonical = fs::weakly_canonical(absolute, ec);
  if (ec) return outside;
  for (const fs::path& root : roots_) {
    const fs::path rel = canonical.lexically_relative(root);
    if (!rel.empty() && *rel.begin() != ".." && rel != ".") return canonical.string();
  }
  return outside;
}

}  // namespace lightlink::service
