// The files an OBJ scene reads besides itself, for the artifact cache key: every `mtllib`
// and, in those libraries, the `map_Kd`/`map_Ke` textures the loader decodes. Each is read
// through SceneFiles (same folder rule as the loader) and appended as (name, size, bytes);
// a missing file is keyed as missing (the loader only warns about it), so restoring or
// editing any of them changes the key. FBX keeps its textures inside a binary format, so
// an FBX scene is keyed by its own bytes alone.
#pragma once

#include <string>
#include <string_view>

#include "core/common/status.h"
#include "core/scene/scene_files.h"

namespace lightlink::scene {

// Empty for a scene file that is not .obj.
Expected<std::string> objDependencyBytes(const SceneFiles& files, std::string_view obj_text);

}  // namespace lightlink::scene
