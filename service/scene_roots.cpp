#include "service/scene_roots.h"

#include "core/scene/scene_files.h"

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
  // Every link followed, dangling ones too: a link in a root to a missing file elsewhere must
  // not read as "missing inside the root".
  Expected<fs::path> resolved = scene::resolvePath(requested);
  if (!resolved) return outside;
  const fs::path& canonical = *resolved;
  for (const fs::path& root : roots_) {
    const fs::path rel = canonical.lexically_relative(root);
    if (!rel.empty() && *rel.begin() != ".." && rel != ".") return canonical.string();
  }
  return outside;
}

}  // namespace lightlink::service
