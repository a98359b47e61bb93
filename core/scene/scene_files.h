// The one way scene ingest touches the file system. A glTF scene names other files (buffer
// and image URIs); a scene from an untrusted source must not make lightlink read whatever
// its user can read. SceneFiles resolves every URI inside the scene file's folder: no `..`
// out, no absolute path, no fallback to the working directory, no symlink that leaves the
// folder (paths are resolved canonically before the check). Only regular files are read,
// opened without blocking, so a FIFO or device named by a scene never hangs a load.
// `FileAccess::allow_outside_folder` lifts the folder rule for trusted scenes (the CLI's
// --allow-outside-scene); the regular-file rule and the no-cwd-fallback rule always hold.
//
// Used by the loader (tinygltf's FsCallbacks), the glTF writer that re-reads the source,
// and the artifact cache key that hashes the files a scene reads.
#pragma once

#include <filesystem>
#include <string>
#include <string_view>

#include <nlohmann/json_fwd.hpp>

#include "core/common/status.h"

namespace tinygltf {
class TinyGLTF;
}

namespace lightlink::scene {

struct FileAccess {
  bool allow_outside_folder = false;
  // Appended to the message of a URI refused for leaving the folder, to say how a trusted
  // scene can be let through (e.g. the CLI's flag); empty: nothing is added.
  std::string outside_hint;
};

class SceneFiles {
 public:
  // The scene file `scene_path` (as given) and its folder, resolved canonically. Reads nothing.
  static Expected<SceneFiles> forScene(const std::string& scene_path, const FileAccess& access);

  const std::string& scenePath() const { return scene_path_; }
  const std::filesystem::path& folder() const { return folder_; }
  const FileAccess& access() const { return access_; }

  // The bytes of the scene file itself (a regular file; not confined: the caller chose it).
  Expected<std::string> readScene() const;

  // Where the (percent-encoded) URI of entry `what` ("buffers[0].uri") points, checked
  // against the folder rule; the file need not exist.
  Expected<std::filesystem::path> resolveUri(const std::string& uri, std::string_view what) const;
  // The bytes of the file that URI names (regular files only).
  Expected<std::string> readUri(const std::string& uri, std::string_view what) const;

  // As resolveUri/readUri for a plain file name (an OBJ `mtllib` or `map_Kd`, an FBX texture
  // path): taken literally, no %XX decoding, under the same folder rule.
  Expected<std::filesystem::path> resolveName(const std::string& name, std::string_view what) const;
  Expected<std::string> readName(const std::string& name, std::string_view what) const;

  // Checks every external `buffers[i].uri` and `images[i].uri` of the glTF JSON `json_text`
  // against the folder rule (and that what it names, if anything, is a regular file), naming
  // the first entry that fails. Data URIs are skipped; malformed JSON passes (the loader
  // names that problem).
  Status checkUris(std::string_view json_text) const;
  // The same on JSON already parsed (a discarded or non-object value passes).
  Status checkUris(const nlohmann::json& gltf) const;

  // Points `loader`'s file callbacks at this object (which must outlive the loads): reads
  // only what resolveUri accepts, never searches the working directory, never writes.
  void install(tinygltf::TinyGLTF& loader) const;

  // tinygltf's own decoding of a URI into a file name (%XX escapes, '+' as space), so the
  // checks see exactly the name tinygltf will ask for.
  static std::string decodeUri(std::string_view uri);

  // True when the absolute path `p` (already canonical) lies inside the folder.
  bool insideFolder(const std::filesystem::path& p) const;

 private:
  SceneFiles() = default;
  Expected<std::filesystem::path> resolveDecoded(const std::string& name, std::string_view shown,
                                                 std::string_view what) const;
  std::string scene_path_;
  std::filesystem::path folder_;  // canonical, absolute
  FileAccess access_;
};

// `path` made absolute with every symbolic link resolved, dangling ones included (their
// target is followed even though it does not exist, unlike weakly_canonical), and `.`/`..`
// folded: the place the kernel would look. Fails only on a link loop or unreadable link.
Expected<std::filesystem::path> resolvePath(const std::filesystem::path& path);

// Reads a whole regular file; a FIFO, device, socket or directory is refused without
// blocking. `what` names the file in messages.
Expected<std::string> readRegularFile(const std::filesystem::path& path, std::string_view what);

// Reads the regular file `inside`, a path already checked to lie in `folder`, letting the
// kernel resolve it again beneath `folder`: a link swapped into the path after the check
// cannot lead out (refused as escaping). Where the kernel lacks openat2, the check stands alone.
Expected<std::string> readRegularFileBeneath(const std::filesystem::path& folder, const std::filesystem::path& inside,
                                             std::string_view what);

}  // namespace lightlink::scene
