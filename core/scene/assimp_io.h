// An Assimp::IOSystem over SceneFiles, so every file an OBJ or FBX pulls in (an OBJ's
// `mtllib`, anything else assimp opens by name) is read under the same rules as a glTF's
// URIs: inside the scene's folder unless FileAccess allows outside, regular files only,
// never written. The scene file itself is handed to assimp from memory by the loader, so
// this only sees the names the file mentions. A read refused by the folder rule is kept
// (assimp would carry on without the file) so the loader can fail naming it; a name not
// found is kept so the loader can warn.
#pragma once

#include <string>
#include <vector>

#include <assimp/IOSystem.hpp>

#include "core/scene/scene_files.h"

namespace lightlink::scene {

class ConfinedIOSystem : public Assimp::IOSystem {
 public:
  // `what` names the files in messages ("mtllib" for an OBJ).
  ConfinedIOSystem(const SceneFiles& files, std::string what) : files_(files), what_(std::move(what)) {}

  bool Exists(const char* file) const override;
  char getOsSeparator() const override { return '/'; }
  Assimp::IOStream* Open(const char* file, const char* mode = "rb") override;
  void Close(Assimp::IOStream* stream) override;

  // The first refusal's message (a name leaving the folder, a FIFO...); empty if none.
  const std::string& refused() const { return refused_; }
  // Names asked for that do not exist, in order, each once.
  const std::vector<std::string>& missing() const { return missing_; }

  // A name as the scene wrote it, made relative to the scene folder where assimp prefixed
  // that folder, with Windows separators turned into '/'.
  std::string normalise(const std::string& name) const;

 private:
  const SceneFiles& files_;
  std::string what_;
  mutable std::string refused_;
  mutable std::vector<std::string> missing_;
};

}  // namespace lightlink::scene
