// SessionStore: the daemon's memory across restarts, `<cache-dir>/sessions.json`.
//
// For every resident scene it records the id, the scene token, the source file, the open
// parameters, the current light set and its version, and its lighting scenarios. A restarted daemon re-opens each
// scene from its cached artifact (nothing is recomputed when the artifact is intact) with
// the same id and token, so clients carry on, and versions keep growing. The file holds
// secrets (scene tokens): it is written with mode 0600, atomically (temp file, fsync,
// rename, directory fsync), so a crash leaves the previous or the new file, never half.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "core/common/status.h"

namespace lightlink::service {

// 2 added `scenarios`; version 1 files (no scenarios) are still read.
inline constexpr int kSessionsSchemaVersion = 2;

struct SessionRecord {
  std::string id, token, name;
  std::string source_path, source_label;
  nlohmann::json params;      // OpenSceneRequest parameters (see paramsToJson in scene_registry.cpp)
  nlohmann::json lights;      // LightSet::toJson
  std::uint64_t version = 0;  // the light set's version
  nlohmann::json scenarios = nlohmann::json::object();  // lighting scenarios: name -> LightSet::toJson
};

// Reads the file; a missing file is an empty list, a malformed one an error naming it.
Expected<std::vector<SessionRecord>> loadSessions(const std::string& path);
Status saveSessions(const std::string& path, const std::vector<SessionRecord>& records);

// Writes `bytes` to `path` atomically (temp + fsync + rename + directory fsync), with
// exactly `mode` (set explicitly: the umask does not apply; private by default).
Status writeFileAtomic(const std::string& path, std::string_view bytes, unsigned mode = 0600);

}  // namespace lightlink::service
