// Scene roots: the folders under which OpenScene may name a scene by path (`--scene-root`,
// repeatable; `scene_roots` in the config file). With none, opening by path is refused and
// only uploaded scenes (gltf_bytes) are accepted. A requested path is resolved canonically
// (symbolic links followed, `..` folded) before the prefix check, and every path outside the
// roots gets one and the same answer, whether or not it exists, so OpenScene is no oracle
// for files elsewhere on the daemon's machine.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "core/common/status.h"

namespace lightlink::service {

class SceneRoots {
 public:
  SceneRoots() = default;  // no roots: every path is refused
  // Each entry must be an existing directory; kept in canonical form.
  static Expected<SceneRoots> resolve(const std::vector<std::string>& dirs);

  bool empty() const { return roots_.empty(); }
  const std::vector<std::filesystem::path>& roots() const { return roots_; }

  // The canonical form of `requested` when it lies under a root. Otherwise a Status whose
  // code and text depend only on whether roots are configured (the daemon answers it as
  // PERMISSION_DENIED).
  Expected<std::string> admit(const std::string& requested) const;

 private:
  std::vector<std::filesystem::path> roots_;
};

}  // namespace lightlink::service
